"""Where each number sits in the flat arrays the compiled twin works on (one place for the layout).

The numba kernels take plain float64 arrays instead of objects so that the
inner loop runs on scalars without Python in it. Four arrays travel together:

``phys``  physical constants (SI units, output side for the gear and load,
          motor side for the motor), written once by :func:`params.pack`
          (and by :meth:`Twin.set_play` for wear);
``fw``    the firmware's constants (gains in the vendor's units, rates);
``state`` everything that changes: the bodies, the winding current, the
          output stage, the drive's registers, the counters;
``mem``   the firmware's own memory (integrators, previous errors, filters).

Integer settings (sub-steps per tick, which encoder the loop reads, the
firmware kind) are stored as floats in ``fw``; they are small whole numbers
and exact in float64.
"""

from __future__ import annotations

# --- phys: physical constants -------------------------------------------------
P_H = 0  # integration sub-step, s
P_J_M = 1  # rotor inertia (with the gear's input stage), kg m^2
P_B_M = 2  # motor-side viscous friction, N m s/rad
P_TC_M = 3  # motor-side Coulomb friction, N m
P_TS_M = 4  # motor-side break-away (static) friction, N m
P_VS_M = 5  # motor-side Stribeck velocity, rad/s (0: no Stribeck hump)
P_KT = 6  # torque constant, N m/A
P_KE = 7  # back-EMF constant, V s/rad
P_R = 8  # winding (+ bridge) resistance, ohm
P_L = 9  # winding inductance, H (0: current follows the voltage at once)
P_EL_DECAY = 10  # exp(-h R / L): the exact one-sub-step decay of the winding current
P_VSUP = 11  # supply voltage: terminal voltage at duty 1, V
P_DUTY_MAX = 12  # largest duty the output stage can make, in (0, 1]
P_N = 13  # gear ratio, motor rad per output rad
P_HALF_PLAY = 14  # half the play, rad at the output
P_K = 15  # gear stiffness in contact, N m/rad at the output
P_C = 16  # gear damping in contact, N m s/rad at the output
P_ETA = 17  # gear efficiency, (0, 1]
P_J_L = 18  # load inertia, kg m^2
P_B_L = 19  # load viscous friction, N m s/rad
P_TC_L = 20  # load Coulomb friction, N m
P_TS_L = 21  # load break-away friction, N m
P_VS_L = 22  # load Stribeck velocity, rad/s
P_MGL = 23  # gravity torque amplitude m g l, N m (torque -m g l sin(theta_load))
P_CPR_M = 24  # motor encoder counts per motor revolution (0: none)
P_CPR_L = 25  # load encoder counts per output revolution (0: none)
P_NOISE_M = 26  # motor encoder noise, counts (standard deviation)
P_NOISE_L = 27  # load encoder noise, counts
P_SIZE = 28

# --- fw: firmware constants ---------------------------------------------------
F_KIND = 0  # FW_* below
F_SPT = 1  # sub-steps per control (motion) tick
F_SPC = 2  # sub-steps per current tick (== F_SPT for voltage-mode firmware)
F_LOOP_ENC = 3  # ENC_MOTOR or ENC_LOAD: the encoder the loop closes on
F_DT = 4  # control tick, s
F_DT_C = 5  # current tick, s
F_SP_MIN = 6  # lowest set point the firmware accepts, output rad
F_SP_MAX = 7  # highest, output rad
F_VEL_TAU = 8  # time constant of the drive's velocity filter, s (0: raw difference)
F_PLL_BW = 9  # encoder PLL bandwidth, rad/s (> 0: the loop uses the PLL, as an ODrive does)
# PID-to-PWM firmware (Dynamixel, Feetech): gains in the vendor's units
F_KP = 10  # output units per count of error
F_KI = 11  # output units per count-tick of summed error
F_KD = 12  # output units per count of error change per tick
F_OUT_LIMIT = 13  # output limit, vendor units (Dynamixel PWM Limit, Feetech torque limit)
F_OUT_FULL = 14  # vendor units that mean 100 % duty (885, 1000)
F_DEADBAND = 15  # error band (counts) inside which the output is off (Feetech insensitive zone)
F_MIN_OUT = 16  # smallest output outside the dead band, vendor units (Feetech minimum startup force)
# cascade (position P -> velocity PI -> current PI), in the loop encoder's shaft units
F_POS_KV = 17  # position gain, 1/s
F_VEL_KP = 18  # velocity P gain, A per rad/s
F_VEL_KI = 19  # velocity I gain, A per rad (A per rad/s per s)
F_VEL_LIMIT = 20  # velocity command limit, rad/s (inf: none)
F_OVERSPEED = 21  # fault when |velocity| > this x the limit (inf: never)
F_INT_DECAY = 22  # velocity integrator factor per tick while limited (< 1: ODrive's decay; 1: hold)
F_CUR_KP = 23  # current P gain, V/A
F_CUR_KI = 24  # current I gain, V/(A s)
F_CUR_LIMIT = 25  # current command limit, A
F_V_LIMIT = 26  # voltage the current loop may ask for, V
F_SIZE = 27

FW_DYNAMIXEL = 0
FW_FEETECH = 1
FW_CASCADE = 2

ENC_MOTOR = 0
ENC_LOAD = 1

# --- state --------------------------------------------------------------------
S_TH_M = 0  # motor angle, motor rad
S_W_M = 1  # motor speed, motor rad/s
S_TH_L = 2  # load angle, output rad
S_W_L = 3  # load speed, output rad/s
S_I = 4  # winding current, A
S_V = 5  # terminal voltage the output stage applies, V
S_STUCK_M = 6  # 1 while the motor sticks
S_STUCK_L = 7  # 1 while the load sticks
S_ENABLED = 8  # 1 with the output stage on
S_FAULT = 9  # 0, or the FAULT_* code that turned the output stage off
S_K = 10  # sub-steps run since reset
S_TORQUE_C = 11  # contact torque the gear applies to the load, N m (latest sub-step)
S_I_CMD = 12  # current set point of a cascade drive, A
# the drive's registers, refreshed at each control tick
S_CNT_M = 13  # motor encoder reading, counts
S_CNT_L = 14  # load encoder reading, counts
S_VEL = 15  # the drive's velocity estimate, output rad/s
S_CUR = 16  # current the drive measured at the tick, A
S_DUTY = 17  # duty the drive commands, -1..1
S_SP = 18  # latched set point, output rad (after the firmware's limits)
S_PENDING = 19  # set point the host sent, waiting for the next tick, output rad
S_HAS_PENDING = 20  # 1 while S_PENDING waits
S_TICK_K = 21  # sub-step count at the latest control tick
# counters
S_N_TICKS = 22  # control ticks run with the output stage on
S_N_SAT = 23  # of those, ticks whose duty was at its limit
S_N_CUR_LIM = 24  # of those, ticks whose current command was at its limit
S_N_STUCK_M = 25  # sub-steps the motor spent stuck with the output stage on
S_N_STUCK_L = 26  # sub-steps the load spent stuck with the output stage on
S_N_CONTACT = 27  # sub-steps with the gear in contact
S_POS_EST = 28  # the drive's position estimate on its loop encoder (PLL or raw), output rad
S_MODE = 29  # MODE_* below: what the set point is
S_SIZE = 30

MODE_POSITION = 0  # the set point is a position, output rad
MODE_TORQUE = 1  # the set point is a motor torque, N m (cascade drives: the current loop alone)

FAULT_NONE = 0
FAULT_OVERSPEED = 1

# --- mem: firmware memory -----------------------------------------------------
M_INT = 0  # position integrator (PID firmware) or velocity integrator (cascade), vendor units / A
M_E_PREV = 1  # previous position error, counts
M_VEL_F = 2  # filtered velocity, loop-shaft rad/s
M_POS_PREV = 3  # previous loop encoder reading, loop-shaft rad
M_PLL_POS = 4  # PLL position, loop-shaft rad
M_PLL_VEL = 5  # PLL velocity, loop-shaft rad/s
M_CUR_INT = 6  # current-loop integrator, V
M_SAT = 7  # 1 if any current tick since the last control tick hit the voltage limit
M_FIRST = 8  # 1 until the first control tick after enable (no previous reading yet)
M_SIZE = 9
