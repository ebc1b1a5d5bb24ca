/*
 * twin_layout.h - where each number sits in the arrays a twin's loop and physics work on.
 *
 * The same layout as servoid.drivers.twin._layout (the Python twin), so that
 * the arrays servoid.drivers.twin.TwinParams.pack() writes can be handed to
 * the firmware as they are (servoid-bench-fw --twin-phys/--twin-fw), and the
 * C loop and physics compute with the same numbers in the same order: a test
 * (tests/drivers/test_serial_twin.py) holds every define here against the
 * Python module. Integer settings are stored as doubles (small whole numbers,
 * exact).
 */
#ifndef SERVOID_TWIN_LAYOUT_H
#define SERVOID_TWIN_LAYOUT_H

/* physical constants (phys[]) */
#define TW_P_H 0
#define TW_P_J_M 1
#define TW_P_B_M 2
#define TW_P_TC_M 3
#define TW_P_TS_M 4
#define TW_P_VS_M 5
#define TW_P_KT 6
#define TW_P_KE 7
#define TW_P_R 8
#define TW_P_L 9
#define TW_P_EL_DECAY 10
#define TW_P_VSUP 11
#define TW_P_DUTY_MAX 12
#define TW_P_N 13
#define TW_P_HALF_PLAY 14
#define TW_P_K 15
#define TW_P_C 16
#define TW_P_ETA 17
#define TW_P_J_L 18
#define TW_P_B_L 19
#define TW_P_TC_L 20
#define TW_P_TS_L 21
#define TW_P_VS_L 22
#define TW_P_MGL 23
#define TW_P_CPR_M 24
#define TW_P_CPR_L 25
#define TW_P_NOISE_M 26
#define TW_P_NOISE_L 27
#define TW_P_SIZE 28

/* firmware constants (fw[]) */
#define TW_F_KIND 0
#define TW_F_SPT 1
#define TW_F_SPC 2
#define TW_F_LOOP_ENC 3
#define TW_F_DT 4
#define TW_F_DT_C 5
#define TW_F_SP_MIN 6
#define TW_F_SP_MAX 7
#define TW_F_VEL_TAU 8
#define TW_F_PLL_BW 9
#define TW_F_KP 10
#define TW_F_KI 11
#define TW_F_KD 12
#define TW_F_OUT_LIMIT 13
#define TW_F_OUT_FULL 14
#define TW_F_DEADBAND 15
#define TW_F_MIN_OUT 16
#define TW_F_POS_KV 17
#define TW_F_VEL_KP 18
#define TW_F_VEL_KI 19
#define TW_F_VEL_LIMIT 20
#define TW_F_OVERSPEED 21
#define TW_F_INT_DECAY 22
#define TW_F_CUR_KP 23
#define TW_F_CUR_KI 24
#define TW_F_CUR_LIMIT 25
#define TW_F_V_LIMIT 26
#define TW_F_SIZE 27

/* the firmware's memory (mem[]) */
#define TW_M_INT 0
#define TW_M_E_PREV 1
#define TW_M_VEL_F 2
#define TW_M_POS_PREV 3
#define TW_M_PLL_POS 4
#define TW_M_PLL_VEL 5
#define TW_M_CUR_INT 6
#define TW_M_SAT 7
#define TW_M_FIRST 8
#define TW_M_SIZE 9

/* firmware kinds (fw[F_KIND]) */
#define TW_FW_DYNAMIXEL 0
#define TW_FW_FEETECH 1
#define TW_FW_CASCADE 2

/* encoder sides (fw[F_LOOP_ENC]) */
#define TW_ENC_MOTOR 0
#define TW_ENC_LOAD 1

/* faults */
#define TW_FAULT_NONE 0
#define TW_FAULT_OVERSPEED 1
#endif
