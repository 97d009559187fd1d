"""The versions of the libraries whose internals jaxclear leans on, and a check against them.

:class:`~jaxclear.integrate.UnrolledExplicitRK` and
:class:`~jaxclear.integrate.ImpactMemorySolver` use diffrax's solver internals (the
wrapped-solver base class, Butcher tableau fields, the step protocol); the engine's speed relies
on XLA:CPU compiler options of jax/jaxlib. ``pyproject.toml`` pins the same bounds; a test fails
with :func:`check` naming the untested version.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

#: package -> (lowest tested version, first untested version): half-open [low, high)
TESTED = {
    "diffrax": ("0.7.0", "0.8"),
    "equinox": ("0.13.0", "0.14"),
    "jax": ("0.10.0", "0.11"),
    "jaxlib": ("0.10.0", "0.11"),
    "optimistix": ("0.1.0", "0.2"),
}


def _key(text: str) -> tuple[int, ...]:
    parts = []
    for piece in text.split(".")[:3]:
        digits = "".join(ch for ch in piece if ch.isdigit()) or "0"
        parts.append(int(digits))
    return tuple(parts + [0] * (3 - len(parts)))


def untested() -> dict[str, str]:
    """``{package: installed version}`` for every package of :data:`TESTED` outside its range."""
    out = {}
    for name, (low, high) in TESTED.items():
        try:
            have = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
            continue
        if not (_key(low) <= _key(have) < _key(high)):
            out[name] = have
    return out


def check() -> None:
    """Raise ``RuntimeError`` naming every installed version outside the tested range."""
    bad = untested()
    if bad:
        ranges = ", ".join(f"{n} {v} (tested: >={TESTED[n][0]},<{TESTED[n][1]})" for n, v in bad.items())
        raise RuntimeError(
            f"jaxclear is tested with other versions than these: {ranges}. Its solver wrappers use "
            "diffrax internals; install the tested versions (pip install -e .) or re-run the tests "
            "and widen the bounds in pyproject.toml and jaxclear/integrate/_versions.py together."
        )
