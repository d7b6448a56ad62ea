"""Small-system settings for the box tests.

The physics tests keep Table I's contact law and Δt = t_c/50 (≈ 141,000 steps per period)
and make runs cheap by shrinking the system instead: a narrow box (Lx = 6σ, a crystal of
rows 6/5 or 5/5) of a few dozen disks costs ~0.2-0.4 s per period. Test-only settings;
never in the scale configs.
"""

import copy

import pytest

PHYSICS = {
    "Lx": 6.0,
    "kappa_n": 1.0e6,
    "kappa_t": 1.0e4,
    "gamma_n": 100.0,
    "gamma_t": 100.0,
    "mu": 0.6,
    "mu_bottom": 0.6,
    "mu_side_walls": 0.6,
    "omega": 1.0,
    "steps_per_contact": 50.0,
}
INIT = {
    "crystal_rows": "spanning",
    "crystal_noise": 1.0e-6,
    "crystal_relax_time": 0.5,
    "random_packing_fraction": 0.35,
    "settle_kinetic_energy": 1.0e-7,
    "settle_max_time": 40.0,
}
PROTOCOL = {
    "start_phase": "sine",
    "ramp_periods": 1.0,
    "transient_periods": 2,
    "measured_periods": 2,
    "periods_per_part": 1,
    "phases_per_period": 16,
}
SECTION = {
    "physics": {k: v for k, v in PHYSICS.items() if k != "mu_side_walls"},
    "init": INIT,
    "protocol": PROTOCOL,
    "grid": {
        "N_l": [5],
        "Gamma": [0.7, 2.0],
        "inits": ["crystal", "random"],
        "mu_side_walls": [0.6],
        "replicas": 1,
    },  # fmt: skip
    "detection": {
        "convection_s_c": 1.0,
        "bouncing_s_b": 1.0 / 30.0,
        "detachment_gap": 1.0e-3,
        "detachment_fraction": 0.02,
        "roll_significance": 3.0,
        "roll_displacement": 1.0,
    },
    "slips": {
        "displacement": 0.2,
        "min_neighbours": 2,
        "neighbour_cutoff": 1.2,
        "surface_depth": 1.0,
    },
    "order": {"neighbour_cutoff": 1.2, "threshold": 0.7, "crystal_min_psi6": 0.9},
    "fits": {
        "breakpoints_random": 1,
        "breakpoints_crystal": 1,
        "confidence": 0.95,
        "bootstrap": 100,
        "N_l": None,
    },
    "resources": {"ns_per_particle_step": 300.0, "min_runtime": 10, "mem_mb": 1000},
}


@pytest.fixture
def section():
    """A complete box config section for a tiny system (test-only)."""
    return copy.deepcopy(SECTION)
