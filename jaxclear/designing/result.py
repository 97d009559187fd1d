"""What a design returns and writes: :class:`DesignResult` (an :class:`~jaxclear.AbstractResult`:
``design.json``, ``design_history.csv``, ``design.png``, ``design.toml``)."""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field

import numpy as np

from .._results import AbstractResult, deprecated
from .._storage import atomic_write_json, atomic_write_text, jsonable
from ..mechanisms.files import save_mechanism
from .figures import plot_comparison

#: Outcomes of a design's optimisation (:attr:`DesignResult.status`): ``converged`` (the method's
#: stopping rule met, constraints held), ``max_iter`` (stopped on the iteration limit, constraints
#: held), ``infeasible`` (no design found that meets the constraints: ``least_violation`` says how
#: close one came), ``stopped`` (the method ended otherwise, e.g. a line search that found no
#: decrease: ``message``).
#:
#: These are not run statuses and not a status system of their own: the status of every run a
#: design makes is a :class:`~jaxclear.RESULTS` code (the journal's ``status`` lists, the start
#: design's error), while these words say how SciPy's optimiser ended, once per design, on the
#: host. Like a fit's ``stop_reason`` and a posterior's ``converged`` they are never an array,
#: never traced and never raised (an ``infeasible`` design is a result, exit code 3 on the command
#: line), so they stay words of the report (``design.json``'s ``"status"``, kept under that key
#: for the files already written) rather than members of :class:`~jaxclear.RESULTS`, whose codes
#: mean runs.
OUTCOMES = ("converged", "max_iter", "infeasible", "stopped")


def __getattr__(name: str):
    """``STATUSES``, deprecated: :data:`OUTCOMES` (the optimisation's outcome, not a run status)."""
    if name == "STATUSES":
        import warnings

        warnings.warn("jaxclear.designing.STATUSES is deprecated: use jaxclear.designing.OUTCOMES (the optimisation's "
                      "outcome; run statuses are jaxclear.RESULTS codes); it will be removed in the next release",
                      DeprecationWarning, stacklevel=2)
        return OUTCOMES
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass
class DesignResult(AbstractResult):
    """The outcome of :func:`jaxclear.design` (:meth:`to_dict`, :meth:`write`, :meth:`summary`,
    :meth:`plot`: :class:`~jaxclear.AbstractResult`).

    Attributes:
        status: the optimisation's outcome, one of :data:`OUTCOMES` (not a run status: see
            there); ``success`` is True only for ``converged``.
        message: the method's own words on why it stopped.
        design: variable name -> value at the optimum [SI].
        start: variable name -> value at the start [SI].
        objective: ``{"name", "description", "unit", "start", "optimum", "improvement"}`` with
            ``improvement = 1 - optimum / start``.
        constraints: per constraint ``{"name", "kind" ("eq"/"ineq"), "start", "optimum",
            "satisfied"}`` (residuals in the SciPy convention: ``>= 0`` met, or ``= 0``).
        gradient: variable -> derivative of the objective at the optimum [objective unit per
            variable unit].
        gradient_norm: norm of the gradient in unit coordinates, the objective divided by its
            start value, the components that push against an active bound removed (0 at a
            bounded stationary point).
        sensitivity: variable -> ``{"gradient", "elasticity" (x/f df/dx), "change_minus",
            "change_plus"}``: the objective's change, as a fraction of its start value, when the
            variable moves 1 % of its range down / up from the optimum (simulated, a bound
            clipped): how much a manufacturing tolerance costs.
        iterations: the method's iterations.
        evaluations: ``{"values", "gradients", "replayed"}`` (replayed: answered from the journal).
        runs: simulations of the member runs, replayed ones included.
        gradient_cost: measured wall time of a gradient evaluation in value evaluations.
        wall_time_s: this call's wall time.
        history: per iteration ``{"iteration", "objective", "violation", "gradient_norm",
            "design", "evaluations", "gradients", "runs", "wall_s"}``.
        chaos: the horizon of predictability at the start (:mod:`jaxclear.designing.chaos`) and the
            spread between the plain and the sensitivity solve's objective; None if not checked.
        least_violation: with status ``infeasible``: ``{"violation", "design"}`` of the evaluated
            design that came closest.
        settings: the problem's settings (variables' ranges, method, runs, tolerances, members).
        mechanism: the optimum as a mechanism (not written to JSON; ``design.toml`` holds it as
            a mechanism file).
        start_mechanism: the start design as a mechanism.
        comparison: the runs of the comparison figure (``plots=True``).
    """

    status: str
    message: str
    design: dict
    start: dict
    objective: dict
    constraints: list
    gradient: dict
    gradient_norm: float
    sensitivity: dict
    iterations: int
    evaluations: dict
    runs: int
    gradient_cost: float
    wall_time_s: float
    history: list
    chaos: dict | None
    settings: dict
    least_violation: dict | None = None
    mechanism: object = field(default=None, repr=False)
    start_mechanism: object = field(default=None, repr=False)
    comparison: object = field(default=None, repr=False)

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def to_dict(self) -> dict:
        """The content of ``design.json`` (JSON-ready: NaN as None): every field but the
        mechanisms and the comparison runs, and ``success``."""
        skip = {"mechanism", "start_mechanism", "comparison"}
        out = {k: v for k, v in self.__dict__.items() if k not in skip}
        out["success"] = self.success
        return jsonable(out)

    def to_json(self) -> dict:
        """Deprecated: :meth:`to_dict`."""
        deprecated("DesignResult.to_json()", "DesignResult.to_dict()")
        return self.to_dict()

    def write(self, folder, *, plots: bool = True) -> list[str]:
        """``design_history.csv``, ``design.toml`` (the optimum as a mechanism file), with
        ``plots`` and the comparison runs ``design.png``, and ``design.json`` (last: it says
        whether ``design.toml`` could be written) in ``folder``; returns their paths."""
        folder = os.fspath(folder)
        os.makedirs(folder, exist_ok=True)
        paths = [self.write_history_csv(os.path.join(folder, "design_history.csv"))]
        try:
            paths.append(self.save_mechanism(os.path.join(folder, "design.toml")))
        except Exception as exc:  # noqa: BLE001  (a mechanism the file format cannot hold: say so, keep the rest)
            self.settings["design_toml"] = f"not written: {exc}"
        if plots and self.comparison is not None:
            paths.append(self.plot(os.path.join(folder, "design.png")))
        paths.append(atomic_write_json(os.path.join(folder, "design.json"), self.to_dict()))
        return paths

    def write_json(self, path) -> str:
        """Deprecated: :meth:`write` (``design.json`` in a folder). Writes :meth:`to_dict` to ``path``."""
        deprecated("DesignResult.write_json(path)", "DesignResult.write(folder), which writes design.json and the "
                   "design's other files")
        return atomic_write_json(path, self.to_dict())

    def write_history_csv(self, path) -> str:
        """``design_history.csv``: one row per iteration. Returns the path."""
        return write_history_csv(path, self.history, list(self.design))

    def save_mechanism(self, path) -> str:
        """The optimum as a mechanism file (:func:`jaxclear.save_mechanism`). Returns the path."""
        save_mechanism(self.mechanism, path)
        return os.fspath(path)

    def plot(self, path=None):
        """The start design against the optimum (:func:`jaxclear.designing.figures.plot_comparison`),
        from the runs the design made for it (``comparison``): the figure, or ``path`` once saved
        there."""
        if self.comparison is None:
            raise ValueError("this result holds no comparison runs (design(..., plots=False)?)")
        channel, start, optimum = self.comparison
        fig = plot_comparison(path, channel, start, optimum, self.history, self.objective["unit"],
                              f"{start[0].name}: {self.objective['description']}, start against optimum "
                              f"({change_words(self.objective['improvement'], 1)})")
        return fig if path is None else os.fspath(path)

    def summary(self) -> str:
        """A few lines for a terminal: status, objective, constraints, design, sensitivity."""
        o = self.objective
        unit = f" {o['unit']}" if o["unit"] else ""
        lines = [f"status {self.status} after {self.iterations} iterations ({self.message}); "
                 f"{self.evaluations['values']} evaluations and {self.evaluations['gradients']} gradients, "
                 f"{self.runs} runs, {self.wall_time_s:.1f} s",
                 f"objective ({o['description']}): {o['start']:.6g}{unit} -> {o['optimum']:.6g}{unit} "
                 f"({change_words(o['improvement'])}); projected gradient norm {self.gradient_norm:.3g}"]
        for c in self.constraints:
            lines.append(f"constraint {c['name']}: residual {c['optimum']:.3g} ({'met' if c['satisfied'] else 'NOT met'})")
        width = max(len(n) for n in self.design)
        lines.append(f"  {'variable':<{width}}  {'start':>12}  {'optimum':>12}  {'df/dx':>11}  {'+-1% range (of start)':>22}")
        for n, v in self.design.items():
            s = self.sensitivity.get(n, {})
            change = f"{100 * s.get('change_minus', float('nan')):+.2f}/{100 * s.get('change_plus', float('nan')):+.2f} %"
            lines.append(f"  {n:<{width}}  {self.start[n]:>12.6g}  {v:>12.6g}  {self.gradient[n]:>11.3g}  {change:>22}")
        lines += [f"warning: {said}" for said in (self.chaos or {}).get("warnings", [])]
        if self.least_violation:
            lines.append(f"least constraint violation found: {self.least_violation['violation']:.3g} at "
                         f"{self.least_violation['design']}")
        return "\n".join(lines)


def change_words(improvement: float, digits: int = 2) -> str:
    """The optimum's objective against the start's in words: ``improvement = 1 - f_opt/f_start``
    [-] as ``"2.69 % lower"``, or ``"1.20 % higher"`` where the optimum's is larger (a
    constraint that the start violated)."""
    if not np.isfinite(improvement):
        return "no relative change: the start's objective is 0"
    return f"{abs(100 * improvement):.{digits}f} % {'lower' if improvement >= 0 else 'higher'}"


def write_history_csv(path, history: list, names: list) -> str:
    """The history as CSV (iteration, objective, violation, gradient norm, runs, wall, variables)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["iteration", "objective", "violation", "gradient_norm", "runs", "wall_s", *names])
    for h in history:
        w.writerow([h["iteration"], repr(h["objective"]), repr(h["violation"]), repr(h["gradient_norm"]), h["runs"],
                    f"{h['wall_s']:.3f}", *[repr(h["design"][n]) for n in names]])
    return atomic_write_text(path, buf.getvalue())


__all__ = ["DesignResult", "OUTCOMES", "change_words", "write_history_csv"]
