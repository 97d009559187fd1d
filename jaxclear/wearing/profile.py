r"""The worn bearing: wear depths at bearing nodes turned into a bearing profile.

A wear depth field :math:`w(\beta)` [m] at ``n`` uniform nodes widens the bearing there. Its mean
:math:`\bar w` enlarges the bearing radius (:math:`R_B + \bar w`: the clearance grows by it), the
rest becomes the bearing's :class:`~jaxclear.FourierProfile`, truncated at ``harmonics``
(discrete Fourier coefficients :math:`a_m = (2/n)\sum_j w_j\cos m\beta_j`,
:math:`b_m = (2/n)\sum_j w_j\sin m\beta_j`, exact for a field of at most that many harmonics).
The truncation smooths the worn step at the edges of the pressed region over
:math:`\approx 2\pi R_B/(2M)`; ``harmonics`` sets that resolution and the cost of each profile
evaluation.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from ..contact.hybrid import FourierProfile
from ..model.mechanism import Mechanism


def node_angles(n_nodes: int) -> np.ndarray:
    """Bearing-fixed node angles :math:`2\\pi j/n` [rad] ``(n,)``."""
    return 2.0 * np.pi * np.arange(n_nodes) / n_nodes


def fourier_of_nodes(depth, harmonics: int):
    """``(mean, cos (M,), sin (M,))`` of node values ``depth`` (n,) [m], ``M = harmonics``."""
    n = depth.shape[-1]
    beta = jnp.asarray(node_angles(n))
    m = jnp.arange(1, harmonics + 1, dtype=float)[:, None]
    return (jnp.mean(depth), 2.0 / n * jnp.sum(depth * jnp.cos(m * beta), axis=-1),
            2.0 / n * jnp.sum(depth * jnp.sin(m * beta), axis=-1))


def prepare(mech: Mechanism, index: int, harmonics: int) -> Mechanism:
    """The mechanism ready to wear: the joint's bearing profile padded to ``harmonics`` terms (so
    every worn profile has the same structure and one compilation serves all windows), and the
    hybrid law's layer thickness made explicit (``None`` means the clearance, which would soften
    the contact as the bearing wears; it stays that of the unworn joint)."""
    element = mech.elements[index]
    law = element.law
    old = law.bearing_profile
    if old is not None and old.cos.shape[0] > harmonics:
        raise ParameterError(f"harmonics = {harmonics} is below the bearing profile's {old.cos.shape[0]} terms; "
                             f"allowed range [{old.cos.shape[0]}, n_nodes/2)")
    cos, sin = np.zeros(harmonics), np.zeros(harmonics)
    if old is not None:
        cos[: old.cos.shape[0]], sin[: old.sin.shape[0]] = np.asarray(old.cos), np.asarray(old.sin)
    law = eqx.tree_at(lambda m: m.bearing_profile, law, FourierProfile(cos, sin), is_leaf=lambda x: x is None)
    if law.thickness is None:
        law = eqx.tree_at(lambda m: m.thickness, law, jnp.asarray(element.clearance, float), is_leaf=lambda x: x is None)
    return eqx.tree_at(lambda m: m.elements[index].law, mech, law)


def worn(prepared: Mechanism, index: int, depth) -> Mechanism:
    """``prepared`` (from :func:`prepare`) with the bearing of joint ``index`` worn by ``depth``
    [m] at the nodes ``(n,)``: radius plus the mean, profile plus the harmonics."""
    element = prepared.elements[index]
    profile = element.law.bearing_profile
    mean, cos, sin = fourier_of_nodes(jnp.asarray(depth, float), profile.cos.shape[0])
    new = FourierProfile(profile.cos + cos, profile.sin + sin)
    mech = eqx.tree_at(lambda m: m.elements[index].law.bearing_profile, prepared, new)
    return eqx.tree_at(lambda m: m.elements[index].bearing_radius, mech, element.bearing_radius + mean)


def bearing_deviation(mech: Mechanism, index: int, prepared: Mechanism, n: int = 360):
    """``(angles (n,), radial growth of the bearing [m] (n,))`` of ``mech`` relative to the unworn
    ``prepared``: what the wear has removed, as the profile represents it."""
    beta = node_angles(n)
    worn_el, new_el = prepared.elements[index], mech.elements[index]
    dr = float(new_el.bearing_radius - worn_el.bearing_radius)
    p_new, p_old = new_el.law.bearing_profile, worn_el.law.bearing_profile
    m = np.arange(1, p_new.cos.shape[0] + 1)[:, None]
    dc, ds = np.asarray(p_new.cos - p_old.cos)[:, None], np.asarray(p_new.sin - p_old.sin)[:, None]
    return beta, dr + np.sum(dc * np.cos(m * beta) + ds * np.sin(m * beta), axis=0)
