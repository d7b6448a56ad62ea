"""The contact-law contract: what a law declares, and the leaves the passes call.

A law is one file (e.g. :mod:`granpipe.engine.static_friction`) that declares

* its **parameters** as a :class:`typing.NamedTuple` subclass (the *parameter type*): the
  passes receive an instance, and numba compiles them once per type (and caches them);
* its **capabilities**: spin (torques and angular velocities) and tangential history
  (one elastic shear displacement per contact, carried over list rebuilds). The passes
  read them at compile time (:func:`law_has_spin`, :func:`law_has_history`), so a law
  without spin or history pays nothing for them;
* its **leaves**, implementations of the two generic functions below for its parameter
  type (``numba.extending.overload``; see :func:`law_leaf`): the force of one contact,
  and that force's directional derivative (Jacobian times a vector) with respect to the
  relative position, the relative velocity, both spins and the history;
* a Python-level object (a subclass of :class:`ContactLaw`) that validates the
  parameters and names the parameter type.

The passes of :mod:`granpipe.engine.passes` then give the law forward runs and tangent
dynamics, against disk walls and flat walls. See ``docs/architecture.md``, "Adding a
contact law".

A leaf is called once per contact from a plain loop over contiguous rows; to let LLVM
vectorise that loop it chooses between smooth pieces with expressions
(``a if c else b`` of side-effect-free values) or ``if`` blocks that only assign, and
never leaves early. ``tests/engine/test_contract.py`` checks that every registered law's
loop compiles to packed square roots and divisions.

Why overloads on a parameter type, not functions passed as arguments: numba cannot
cache a kernel that takes a jitted function as an argument across processes (the
cache key holds the function object), but it caches a kernel specialised on a named
tuple type, which pickles by reference to its class. Every file of the engine is part
of the cache stamp (:mod:`granpipe._jit`), so an edit to a law recompiles the passes
that inline it.

Conventions of one contact: the normal ``n`` points from j to i, the tangent is
``t = e_z x n = (-n_y, n_x)``, the contact point lies at the middle of the overlap
(lever arms ``l_i + l_j = r``), forces are on i (j feels the opposite) and torques are
counter-clockwise positive. A flat wall is the j side made infinitely heavy and not
turning, with curvature ``1/r = 0`` (its normal does not turn).
"""

from __future__ import annotations

import inspect
import math
from typing import ClassVar, NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

from granpipe._jit import JIT_OPTIONS, njit
from granpipe.errors import ConfigError

__all__ = [
    "ContactLaw",
    "Contact",
    "Perturbation",
    "pair_force",
    "pair_force_jvp",
    "perturbed_kinematics",
    "perturbed_force",
    "truncated_spring",
    "truncated_spring_jvp",
    "law_leaf",
    "law_has_spin",
    "law_has_history",
    "registered_laws",
    "checked_parameter",
    "evaluate_pair",
    "evaluate_pair_jvp",
]

_REGISTRY: dict[str, type] = {}


class Contact(NamedTuple):
    """One contact as the leaves see it (every field a float).

    Attributes
    ----------
    nx, ny : float
        Unit normal from j to i.
    delta : float [length]
        ``r - (a_i + a_j)`` (the negative overlap; the contact exists for ``delta <= 0``).
    curv : float [1/length]
        ``1/r``, the rate at which the normal turns with the relative position; 0 for a
        flat wall (its normal does not turn).
    lever_i, lever_j : float [length]
        Distances from the centres to the contact point (``(r + a_i - a_j)/2`` and
        ``(r + a_j - a_i)/2``).
    vx, vy : float [length/time]
        Relative velocity ``v_i - v_j`` (half-step velocities in the step).
    w_i, w_j : float [1/time]
        Spins (0 for a law without spin).
    m_eff : float [mass]
        ``m_i m_j / (m_i + m_j)`` (``m_i`` against a wall).
    """

    nx: float
    ny: float
    delta: float
    curv: float
    lever_i: float
    lever_j: float
    vx: float
    vy: float
    w_i: float
    w_j: float
    m_eff: float


class Perturbation(NamedTuple):
    """A tangent vector's components at one contact (every field a float): of the
    relative position ``(ddx, ddy)`` [length], the relative velocity ``(dvx, dvy)``
    [length/time], both spins [1/time] and the history before the step ``dxi``
    [length]."""

    ddx: float
    ddy: float
    dvx: float
    dvy: float
    dw_i: float
    dw_j: float
    dxi: float


def pair_force(law, c, xi, dt):
    """Force of one contact (a generic leaf; each law implements it for its type).

    Parameters
    ----------
    law : the law's parameter type (a NamedTuple)
    c : :class:`Contact`
    xi : float [length]
        Shear history along ``t`` before this evaluation (0 for a law without history).
    dt : float [time]
        Step by which the history advances (0: evaluate without advancing).

    Returns
    -------
    fx, fy : float
        Force on i.
    tau_i, tau_j : float
        Torques on i and j.
    xi_new : float
        History after the evaluation.
    f_n, f_t : float
        Normal and tangential force components (along ``n`` and ``t``).
    piece : int
        Which smooth piece of the law applied (the law's own codes); passed back to
        :func:`pair_force_jvp`.
    """
    raise NotImplementedError("a generic leaf: implemented per law (numba overload)")


def pair_force_jvp(law, c, f_n, f_t, piece, dt, p):
    """Directional derivative of :func:`pair_force` at the point it was evaluated.

    ``c`` and ``dt`` as for :func:`pair_force`, with its outputs ``f_n, f_t, piece``;
    ``p`` the :class:`Perturbation`. Exact on each smooth piece.

    Returns
    -------
    dfx, dfy, dtau_i, dtau_j, dxi_new : float
    """
    raise NotImplementedError("a generic leaf: implemented per law (numba overload)")


@njit
def perturbed_kinematics(c, p):
    """The perturbed kinematics of contact ``c`` (:class:`Contact`) under ``p``
    (:class:`Perturbation`), shared by the Jacobian leaves.

    A perturbation ``dd`` of the relative position turns the normal by
    ``psi = curv (t . dd)`` (``dn = psi t``, ``dt = -psi n``; ``curv = 1/r``, 0 for a flat
    wall) and moves the mid-overlap lever arms by ``dr/2`` with ``dr = n . dd``.

    Returns
    -------
    psi, dr : float
    dvn, dvt : float
        Perturbations of the normal relative velocity and of the slip velocity at the
        contact point ``v . t - l_i w_i - l_j w_j``.
    """
    nx, ny = c.nx, c.ny
    psi = c.curv * (p.ddy * nx - p.ddx * ny)
    dr = p.ddx * nx + p.ddy * ny
    vn = c.vx * nx + c.vy * ny
    ut = c.vy * nx - c.vx * ny
    dvn = p.dvx * nx + p.dvy * ny + psi * ut
    dlev = 0.5 * dr
    dvt = (
        p.dvy * nx - p.dvx * ny - psi * vn - dlev * (c.w_i + c.w_j)
        - c.lever_i * p.dw_i - c.lever_j * p.dw_j
    )  # fmt: skip
    return psi, dr, dvn, dvt


@njit
def perturbed_force(c, psi, dr, f_n, f_t, dfn, dft):
    """``(dF_x, dF_y, dtau_i, dtau_j)`` of ``F = f_n n + f_t t``, ``tau = -l f_t`` at
    contact ``c`` from the perturbed components ``dfn, dft`` and the frame's turn ``psi``
    (lever arms + dr/2)."""
    a = dfn - f_t * psi  # along n
    b = f_n * psi + dft  # along t
    dlev = 0.5 * dr
    return (
        a * c.nx - b * c.ny,
        a * c.ny + b * c.nx,
        -dlev * f_t - c.lever_i * dft,
        -dlev * f_t - c.lever_j * dft,
    )


@njit
def truncated_spring(k_t, inv_k_t, xi, u, damp, cap, dt):
    """The tangential spring with history truncated at Coulomb (Cundall & Strack 1979, as
    LAMMPS' ``gran/hooke/history``), shared by the laws with history: ``xi' = xi + u dt``,
    ``f_t = -k_t xi' - damp``; where ``|f_t| > cap`` (slip) ``f_t = cap sign(f_t)`` and
    the spring is reset, ``xi' = -(f_t + damp) inv_k_t`` (``inv_k_t = 1/k_t``, or 0 for a
    law that keeps no elastic shear). Returns ``(f_t, xi', slip)``."""
    xi_new = xi + u * dt
    f_t = -k_t * xi_new - damp
    slip = abs(f_t) > cap
    capped = cap if f_t > 0.0 else -cap
    xi_new = -(capped + damp) * inv_k_t if slip else xi_new
    f_t = capped if slip else f_t
    return f_t, xi_new, slip


@njit
def truncated_spring_jvp(k_t, inv_k_t, dxi, du, ddamp, dft_capped, stick, dt):
    """The perturbations ``(df_t, dxi')`` of :func:`truncated_spring` on its piece: the
    spring's where it sticks, else ``dft_capped`` (the cap's) with the reset spring's."""
    dxi_stick = dxi + du * dt
    dft = -k_t * dxi_stick - ddamp if stick else dft_capped
    dxi_new = dxi_stick if stick else -(dft_capped + ddamp) * inv_k_t
    return dft, dxi_new


def _instance_class(law):
    return law.instance_class if isinstance(law, types.BaseNamedTuple) else None


def law_leaf(generic, params_type):
    """Decorator: the implementation of ``generic`` (:func:`pair_force` or
    :func:`pair_force_jvp`) for the parameter type ``params_type``.

    The decorated function has the generic's signature and is compiled, with the project's
    JIT options (:data:`granpipe._jit.JIT_OPTIONS`), into the passes whenever they run
    with an instance of ``params_type``::

        @law_leaf(pair_force, StaticFrictionParams)
        def _force(law, c, xi, dt):
            ...
    """

    def register(impl):
        def typer(law, *args):
            return impl if _instance_class(law) is params_type else None

        # numba checks that the typer and the implementation have one signature
        typer.__signature__ = inspect.signature(impl)
        typer.__name__ = f"{generic.__name__}_{params_type.__name__}"
        overload(generic, jit_options=JIT_OPTIONS)(typer)
        return impl

    return register


def _capability(name):
    """A function of a law's parameter object that numba folds to the constant its law
    declares (``has_spin`` or ``has_history``): the passes branch on it at compile time."""

    def capability(law):
        return bool(getattr(_law_of_params(type(law)), name))

    capability.__name__ = f"law_{name}"

    @overload(capability, jit_options=JIT_OPTIONS)
    def _typer(law):
        cls = _law_of_params(_instance_class(law))
        if cls is None:
            return None
        flag = bool(getattr(cls, name))
        return lambda law: flag

    return capability


def _law_of_params(params_type):
    return next((c for c in _REGISTRY.values() if c.params_type is params_type), None)


law_has_spin = _capability("has_spin")
law_has_spin.__doc__ = "Whether the law of parameter object ``law`` has spin (a constant)."
law_has_history = _capability("has_history")
law_has_history.__doc__ = "Whether the law of ``law`` keeps a shear history (a constant)."


class ContactLaw:
    """Base of the Python-level law objects handed to :class:`granpipe.engine.Simulation`.

    A subclass declares ``name``, ``law_id`` (a small integer stored in states, so a state
    is never run under another law), the capabilities ``has_spin`` and ``has_history``,
    its ``params_type`` (the NamedTuple its leaves are registered for), and implements
    :meth:`params`. Subclasses register themselves.
    """

    name: ClassVar[str] = ""
    law_id: ClassVar[int] = -1
    has_spin: ClassVar[bool] = False
    has_history: ClassVar[bool] = False
    params_type: ClassVar[type] = type(None)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.name:
            other = next((c for c in _REGISTRY.values() if c.law_id == cls.law_id), None)
            if other is not None and other.name != cls.name:
                raise TypeError(f"law_id {cls.law_id} of {cls.name} is taken by {other.name}")
            _REGISTRY[cls.name] = cls

    def params(self):
        """The instance of :attr:`params_type` the leaves take at disk pairs."""
        raise NotImplementedError

    def wall_params(self) -> tuple:
        """The leaves' parameters at the three flat walls (left, right, bottom); the pair
        parameters by default (a law whose walls grip differently overrides it)."""
        p = self.params()
        return (p, p, p)

    def pair(self, d, v, spin_i, spin_j, radius_i, radius_j, m_eff, xi=0.0, dt=0.0):
        """One contact through the law's leaf (:func:`pair_force`), for tests and studies.

        Parameters
        ----------
        d, v : (2,) float
            ``r_i - r_j`` and ``v_i - v_j``.
        spin_i, spin_j : float [1/time]
        radius_i, radius_j : float [length]
        m_eff : float [mass]
        xi : float [length]
            Shear history before the evaluation.
        dt : float [time]
            Step by which the history advances.

        Returns
        -------
        (5,) float64 ``(F_x, F_y, tau_i, tau_j, xi_new)`` (zeros when apart), and the
        piece (int; -1 when apart).
        """
        g = _pair_geometry(d, radius_i, radius_j)
        if g is None:
            return np.zeros(5), -1
        out = evaluate_pair(
            self.params(), _contact(g, v, spin_i, spin_j, m_eff), float(xi), float(dt)
        )
        return np.array(out[:5]), int(out[7])

    def pair_jacobian(self, d, v, spin_i, spin_j, radius_i, radius_j, m_eff, xi=0.0, dt=0.0):
        """Jacobian (5, 7) of :meth:`pair`'s ``(F_x, F_y, tau_i, tau_j, xi_new)`` with respect
        to ``(d_x, d_y, v_x, v_y, spin_i, spin_j, xi)``, from the law's Jacobian leaf
        (:func:`pair_force_jvp`; exact on the piece the contact is on)."""
        c = _contact(_pair_geometry(d, radius_i, radius_j), v, spin_i, spin_j, m_eff)
        return _jacobian(self.params(), c, xi, dt)

    def wall_pair(self, h, v, spin, radius, mass, normal, xi=0.0, dt=0.0, wall=2):
        """A disk's contact with flat wall ``wall`` (0 left, 1 right, 2 bottom; its
        parameters from :meth:`wall_params`) at distance ``h``, unit ``normal`` into the
        box: the pair law with the wall's side infinitely heavy and not turning, as the
        passes evaluate it (``m_eff = mass``, lever ``radius - overlap/2``).

        Returns
        -------
        (3,) float64 ``(F_x, F_y, tau)`` (zeros when apart), ``xi_new``, and the piece.
        """
        if h - radius > 0:
            return np.zeros(3), 0.0, -1
        c = _wall_contact(h, v, spin, radius, mass, normal)
        out = evaluate_pair(self.wall_params()[wall], c, float(xi), float(dt))
        return np.array([out[0], out[1], out[2]]), out[4], int(out[7])

    def wall_pair_jacobian(self, h, v, spin, radius, mass, normal, xi=0.0, dt=0.0, wall=2):
        """Jacobian (5, 7) of the wall contact (:meth:`wall_pair`, outputs ``(F_x, F_y,
        tau, 0, xi_new)``) with respect to the disk's ``(x, y, v_x, v_y, spin)``, the wall's
        spin (unused) and ``xi``."""
        c = _wall_contact(h, v, spin, radius, mass, normal)
        return _jacobian(self.wall_params()[wall], c, xi, dt)


def _contact(geometry, v, spin_i, spin_j, m_eff) -> Contact:
    """The :class:`Contact` of a disk pair from :func:`_pair_geometry`'s output."""
    nx, ny, r, delta, lev_i, lev_j = geometry
    return Contact(
        float(nx), float(ny), float(delta), 1.0 / float(r), float(lev_i), float(lev_j),
        float(v[0]), float(v[1]), float(spin_i), float(spin_j), float(m_eff),
    )  # fmt: skip


def _wall_contact(h, v, spin, radius, mass, normal) -> Contact:
    """The :class:`Contact` of a disk at distance ``h`` from a flat wall of unit
    ``normal``: the wall's side infinitely heavy and not turning (``m_eff`` the disk's
    mass, lever ``radius - overlap/2``, curvature 0)."""
    n = np.asarray(normal, dtype=np.float64)
    return Contact(
        float(n[0]), float(n[1]), float(h - radius), 0.0, float(radius - 0.5 * (radius - h)),
        0.0, float(v[0]), float(v[1]), float(spin), 0.0, float(mass),
    )  # fmt: skip


def _jacobian(law, c, xi, dt):
    """(5, 7) Jacobian of contact ``c``'s outputs, one :func:`pair_force_jvp` per unit
    :class:`Perturbation`."""
    out = evaluate_pair(law, c, float(xi), float(dt))
    jac = np.zeros((5, 7))
    for k, e in enumerate(np.eye(7)):
        p = Perturbation(*(float(x) for x in e))
        jac[:, k] = evaluate_pair_jvp(law, c, out[5], out[6], out[7], float(dt), p)
    return jac


def _pair_geometry(d, radius_i, radius_j):
    """``(nx, ny, r, delta, lever_i, lever_j)`` of a pair, or None when apart."""
    r = float(np.hypot(d[0], d[1]))
    delta = r - (radius_i + radius_j)
    if delta > 0:
        return None
    return (
        d[0] / r,
        d[1] / r,
        r,
        delta,
        0.5 * (r + radius_i - radius_j),
        0.5 * (r + radius_j - radius_i),
    )


@njit
def evaluate_pair(law, c, xi, dt):
    """:func:`pair_force` called from Python (tests, studies), with its arguments."""
    return pair_force(law, c, xi, dt)


@njit
def evaluate_pair_jvp(law, c, f_n, f_t, piece, dt, p):
    """:func:`pair_force_jvp` called from Python, with its arguments."""
    return pair_force_jvp(law, c, f_n, f_t, piece, dt, p)


def checked_parameter(name: str, value, allow_zero: bool = True) -> float:
    """``value`` as a float, or a :class:`~granpipe.errors.ConfigError` naming ``name``
    unless it is finite and ``>= 0`` (``> 0`` without ``allow_zero``): the check every
    law's ``__post_init__`` makes of its coefficients."""
    value = float(value)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ConfigError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return value


def registered_laws() -> dict[str, type]:
    """``{name: class}`` of every law defined so far (import :mod:`granpipe.engine` first)."""
    return dict(_REGISTRY)
