"""Index constants for the small parameter/counter/accumulator arrays the kernels share.

numba treats module-level integers as compile-time constants, so naming the slots costs
nothing in the hot loops. Everything is SI (m, kg, s, N, Pa, J).
"""

# --- float parameters: prm[...] -------------------------------------------------------
P_DT = 0  # timestep [s]
P_EMOD = 1  # linear effective modulus E* [Pa]
P_KRATIO = 2  # linear normal-to-shear stiffness ratio kappa* [-]
P_FRIC = 3  # ball-ball friction coefficient mu [-]
P_PB_EMOD = 4  # parallel-bond effective modulus E-bar [Pa]
P_PB_KRATIO = 5  # parallel-bond stiffness ratio kappa-bar [-]
P_PB_TEN = 6  # parallel-bond tensile strength sigma-bar_c [Pa]
P_PB_COH = 7  # parallel-bond cohesion c-bar [Pa]
P_PB_TANFA = 8  # tan(phi-bar), parallel-bond friction angle [-]
P_PB_RMUL = 9  # radius multiplier lambda-bar [-]
P_PB_MCF = 10  # moment-contribution factor beta-bar [-]
P_DP_N = 11  # normal critical-damping ratio of the contact dashpot [-]
P_DP_S = 12  # shear critical-damping ratio of the contact dashpot [-]
P_ALPHA = 13  # local (non-viscous) damping coefficient [-]
P_GX = 14  # gravity [m/s^2]
P_GY = 15
P_GZ = 16
P_SKIN = 17  # Verlet skin [m]
P_MAXSPEED = 18  # blow-up guard: any speed above this stops the run [m/s]
P_TIME = 19  # model time [s]
P_VCAP = 20  # >0: speeds are clipped to this value (genesis overlap removal only) [m/s]
P_DBOUND = 21  # upper bound of the largest ball displacement since the last rebuild [m]
P_NOSPIN = 22  # >0: translation only, no torques and no spins (Model.set_spin; genesis relax)
P_MODEL = 23  # contact model of the installed pairs: 0 linearpbond, 1 flatjoint
N_PRM = 24

#: contact models (``P_MODEL``) by PFC name
CONTACT_MODELS = ("linearpbond", "flatjoint")

# --- integer counters: iprm[...] ------------------------------------------------------
I_STEP = 0  # steps taken since the model was created
I_NPAIRS = 1  # ball-ball pairs in use (bond pairs first, then Verlet pairs)
I_NB = 2  # number of bond pairs (fixed once bonds are installed)
I_NSLOTS = 3  # ball-wall candidate slots in use
I_REBUILD = 4  # 1: the neighbour lists must be rebuilt before the next step
I_NREBUILDS = 5  # rebuilds done (diagnostics)
I_NEED_P = 6  # pair capacity needed after an overflow
I_NEED_W = 7  # wall-slot capacity needed after an overflow
I_BAD = 8  # 1 + index of a particle that blew up (0: none)
I_NBROKEN = 9  # bonds broken so far
I_NEED_C = 10  # neighbour-candidate buffer size needed after an overflow
I_FORCES = 11  # 0 forces current, 1 refresh without increments, 2 force-displacement due
N_IPRM = 12

# --- folded energy accumulators: eacc[...] (energy of pairs dropped at rebuilds) ------
E_SLIP = 0  # friction slip dissipation, ball-ball
E_DASH = 1  # dashpot dissipation, ball-ball
E_WSLIP = 2  # friction slip dissipation, ball-wall
E_WDASH = 3  # dashpot dissipation, ball-wall
E_REMOVED = 4  # strain energy of ball-wall contacts deleted with their wall
N_EACC = 5

# --- fixity bits: fix[i] ---------------------------------------------------------------
FIX_VX = 1
FIX_VY = 2
FIX_VZ = 4
FIX_WX = 8
FIX_WY = 16
FIX_WZ = 32
FIX_ALL = 63

# --- wall kinds ------------------------------------------------------------------------
WALL_PLANE = 0  # half-space boundary; balls on the side the normal points to
WALL_CYLINDER = 1  # inside of a cylinder (vessel)

# --- bond states -----------------------------------------------------------------------
BOND_INTACT = 0
BOND_TENSION = 1  # broken in tension
BOND_SHEAR = 2  # broken in shear
BOND_NONE = 3  # never bonded (a flat joint installed as a gapped or slit contact)
