"""granpipe.engine: a small, jitted 2D DEM engine (docs/architecture.md, "The engine").

Disks in the plane (second coordinate vertical), struct-of-arrays float64, velocity
Verlet with gravity, cell lists feeding Verlet lists with a skin, contact laws under one
contract (each a force leaf and its Jacobian leaf; :mod:`granpipe.engine.contract`,
docs/architecture.md "Adding a contact law"), walls with prescribed motion, and tangent
dynamics (the exact linearization of the discrete map), every law through the same
passes (:mod:`granpipe.engine.passes`: gather, the law's rows, scatter).

Objects
-------
``DrumLaw(k_n, gamma_n, gamma_t, mu)``
    Drum paper Eq. 1: linear spring-dashpot, viscous friction capped at Coulomb, no
    spin, damping not scaled by mass. ``.contact_time(m_eff)``, ``.restitution(m_eff)``.
``BoxLaw(kappa_n, kappa_t, gamma_n, gamma_t, mu, mu_wall=None, mu_side=None)``
    Box paper App. A: m_eff-scaled damping, tangential spring with history truncated
    at Coulomb, spin with ``I = m sigma²/8``; ``mu_side = 0``: frictionless side walls.
``StaticFrictionLaw(k_n, gamma_n, gamma_t, mu, k_t=None)``
    The drum's normal law with spin (``I = m d²/8``) and a Cundall–Strack tangential
    spring truncated at Coulomb, ``k_t = k_n/3`` by default (docs/drum.md, "Static
    friction").

Every law has ``.params()`` (its leaves' parameters), ``.pair(...)`` and
``.pair_jacobian(...)`` (5 x 7) for one contact, and ``.wall_pair(...)``,
``.wall_pair_jacobian(...)`` against a flat wall, through its contract leaves.
``WallDisks(centre, omega, omega_after=None, t_switch=inf)``
    Rotation of the disks flagged ``is_wall``, each at its rate times ``omega``
    (counter-clockwise positive; the drum stop is ``omega_after=0`` at ``t_switch``).
``FlatWalls(x_left, x_right, bottom, z0, amplitude, omega, phase, ramp_start, ramp_time,
shaken_sides=False, wall_torque=True)``
    Vertical side lines and a bottom at ``z_b(t) = z0 + A r(t) sin(omega t + phase)``;
    the side walls shaken with the bottom or still; wall friction with or without torque.
``Simulation(law, dt, gravity=(0, -1), wall_disks=None, flat_walls=None, skin=None,
parallel=True, max_overlap=0.5)``
    ``.new_state(positions, radii, masses, *, velocities, spins, is_wall, wall_rate,
    inertia, time) -> State`` (or ``Ensemble`` for a leading replica axis);
    ``.run(state, n_steps, *, stride=0, tangent=False) -> Record`` advances in place;
    ``.set_tangent(state, dr, dv, dspin=None)``, ``.random_tangent(state, rng, fraction=0.1)``;
    ``.refresh(state)`` after editing a state in place; ``.replace(**changes)``;
    ``.set_shear_history(state, pairs, xi)`` gives a rebuilt state its springs back;
    ``.profile_passes(state)`` times each pass of the step loop (seconds per call).
``State`` / ``Ensemble``
    Views ``positions, velocities, forces, spins, torques, radii, masses, is_wall,
    mobile, contacts`` (per-disk contact counts, walls included), ``time``,
    ``wall_angle``, ``tangent`` (dr, dv at true scale), ``tangent_stored``,
    ``tangent_log2_scale``; ``kinetic_energy()``, ``max_speed()``, ``global_speed()``,
    ``speeds()``, ``neighbour_stats()``, ``reset_counters()``, ``copy()``, ``skin``,
    ``shear_history() -> (pairs, xi)`` (the stretched springs of a State);
    ``to_arrays() -> dict`` and ``State.from_arrays(dict)`` save and restore everything
    a run needs to continue bit-identically (netCDF- or ``np.savez``-ready).
    ``Ensemble.stack(states)``, ``ens[r]`` (a State sharing memory). Arrays of an
    ensemble are ``(R, N, ...)``.
``Record``
    ``time (B,)``, ``global_speed``, ``local_lyapunov``, ``lyapunov_count`` (``(B,)`` or
    ``(R, B)``): exact block means over ``stride`` steps.

Conventions
-----------
* One step: half kick, drift, walls, (list rebuild), forces at the half-step
  velocities, half kick. Forces, contact counts, shear histories, the tangent vector,
  the time and the wall angle live in the state, so chunked runs are bit-identical to
  one long run, and replicas run side by side (``Ensemble``, in threads) are
  bit-identical to replicas run alone.
* ``lambda(t) = (1/dt) ln(|du(t)|_S / |du(t - dt)|_S)`` with ``du = (dr, dv)`` of the
  mobile disks (4 per disk, ``dv`` at full steps) and both norms over the set S of
  disks with at least two contacts (walls count) at the force evaluation of step t
  (drum paper Sec. III). Steps where either norm is zero (S empty, or the vector lives
  only on rattlers) are left out of the block mean; ``lyapunov_count`` says how many
  steps entered each block. The vector is renormalised by exact powers of two.
* Bad states (NaN/inf, an overlap deeper than ``max_overlap``) raise
  :class:`granpipe.errors.SimulationError` naming particle, step, time (``other``,
  ``replica``). The Verlet half list (skin default 0.1 of the smallest radius) is rebuilt
  when a disk has moved ``skin/2``; contacts touch at ``r <= a_i + a_j``; shear
  histories live per listed pair and per disk and flat wall, carried over rebuilds.
* Threads: an ensemble's replicas run in up to ``numba.get_num_threads()`` threads; a
  State runs serially without the GIL.

Worked example
--------------
Two disks on a collision course (the drum of docs/drum.md in miniature:
docs/architecture.md, "The engine")::

    from granpipe.engine import DrumLaw, Simulation

    law = DrumLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44)
    sim = Simulation(law, dt=1.14368e-3, gravity=(0.0, 0.0))
    state = sim.new_state([[0.0, 0.0], [1.1, 0.0]], radii=[0.5, 0.5], masses=[1.0, 1.0],
                          velocities=[[1.0, 0.0], [-1.0, 0.0]])
    sim.run(state, 200)
    state.velocities          # [[-0.43, 0], [0.43, 0]]: e = law.restitution(0.5) = 0.43
"""

from granpipe.engine.contract import ContactLaw, registered_laws
from granpipe.engine.laws import BoxLaw, DrumLaw
from granpipe.engine.simulation import Ensemble, Record, Simulation, State
from granpipe.engine.static_friction import StaticFrictionLaw
from granpipe.engine.walls import FlatWalls, WallDisks

__all__ = ["ContactLaw", "StaticFrictionLaw", "registered_laws", "BoxLaw", "DrumLaw"]
__all__ += ["Ensemble", "FlatWalls", "Record", "Simulation", "State", "WallDisks"]
