"""Where the engine keeps things: the rows of the state arrays and of the pair buffer,
and the order of the storage tuple every stepping kernel takes.

Defined once, here, for every module of the engine (:mod:`granpipe.engine.neighbours`,
:mod:`granpipe.engine.walls`, :mod:`granpipe.engine.passes`,
:class:`granpipe.engine.Simulation`).
"""

# rows of vec (NV, N, 2)
POS, VEL, FRC, POS_BUILD, WALL_REF, T_POS, T_VEL, T_FRC, IM2, MOB2, MG = range(11)
NV = 11
# rows of sca (NS, N): T_SPIN, T_TORQUE are the tangent vector's spin and torque (laws
# with spin); XI_LEFT .. XI_BOTTOM the shear histories of each disk against the three
# flat walls and T_XI_LEFT .. their perturbations (laws with history); WALL_RATE a wall
# disk's angular velocity over the wall disks' omega
RADIUS, INV_MASS, INV_INERTIA, SPIN, TORQUE, T_PREV, XI_LEFT, XI_RIGHT, XI_BOTTOM = range(9)
T_SPIN, T_TORQUE = 9, 10
T_XI_LEFT, T_XI_RIGHT, T_XI_BOTTOM = 11, 12, 13
WALL_RATE = 14
NS = 15
# rows of ivec (NI, N)
IS_WALL, CONTACTS, CELL_ITEMS, CELL_OF, PAIR_CONTACTS = range(5)
NI = 5
# rows of pair_c (NPC, P): a_i + a_j, overlap bound, m_eff, a_i - a_j
P_SUM, P_LIM, P_MEFF, P_DIFF = range(4)
NPC = 4
# rows of the pair buffer (NB, P), written by the gather and read by the law's rows:
# relative position and velocity, the tangent vector's differences, the spins and their
# perturbations (laws with spin)
B_DX, B_DY, B_DVX, B_DVY, B_EX, B_EY, B_EVX, B_EVY, B_WI, B_WJ, B_DWI, B_DWJ = range(12)
# written by the law's rows and read by the scatter: force on i, torques on i and j, and
# their perturbations
B_FX, B_FY, B_TI, B_TJ, B_GX, B_GY, B_GTI, B_GTJ = range(12, 20)
# the pair constants and histories, copied along when the pass is compacted
B_S, B_L, B_M, B_D, B_XI, B_DXI = range(20, 26)
NB = 26
# rows of pair_ij (3, P): owner i, partner j, and (compacted passes) the pair index k
PI, PJ, PK = range(3)
# clock (NCLOCK,): time origin, wall angle, its angular velocity over the last step, the
# angle at the last list build, the largest distance of a wall disk from the centre
T_ORIGIN, THETA, LAST_OMEGA, THETA_BUILD, WALL_RMAX = range(5)
ZB_NEAR = 5  # the bottom's height when the near-wall list was built
# the bad-state bound on overlaps, as a fraction of the smaller radius of the pair (set by
# the Simulation; the per-pair bounds P_LIM are derived from it at each list build)
OVERLAP_FRAC = 6
NCLOCK = 7
# counters (NCOUNT,)
STEP, N_PAIRS, N_REBUILDS, FORCE_REBUILD, LOG2_SCALE, CONTACT_SUM, STEPS_RUN, N_WALLS = range(8)
LAST_PAIR_CONTACTS = 8  # contacts among listed pairs at the last evaluation (compaction)
COUNT_STALE = 9  # the per-disk pair-contact counts must be recomputed (list rebuilt)
NEAR_WALLS = 10  # disks in the near-wall list (ivec[CELL_ITEMS]); -1: to be rebuilt
NCOUNT = 11
# info (4,): status, particle, other, step
OK, NONFINITE, DEEP_OVERLAP, LIST_OVERFLOW, TANGENT_NONFINITE = range(5)
# "other" codes for flat walls in info
LEFT_WALL, RIGHT_WALL, BOTTOM_WALL = -1, -2, -3

STORAGE = (
    "vec", "sca", "ivec", "walls", "pair_start", "pair_ij", "pair_c", "pair_xi", "pair_dxi",
    "old_start", "old_j", "old_xi", "old_dxi", "buf", "touch", "flip", "cell_count",
    "cell_start", "clock", "counters",
)  # fmt: skip
"""Storage arrays every stepping kernel takes, as one tuple in this order
(``Simulation``'s ``_storage``; ``passes.replica_of`` picks one replica of it)."""
