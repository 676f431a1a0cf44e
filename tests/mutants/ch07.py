"""Chapter 07 (rotations and IMU mechanisation): plausible mistakes in the exercise's functions.

The solution's cells (ids ``att``, ``att-nb``, ``vel``, ``pos``, ``run``, ``level``) hold
``attitude_step_bn`` (the step of C = R_bn, which the learner derives), ``attitude_step`` (the
R_nb step built from it), ``velocity_step``, ``position_step``, ``mechanise`` and the optional
challenge's ``level_attitude``; an edit of a step graded by the check of a function that calls
it (``attitude_step``, ``mechanisation_run``) tests the dependency-aware hint. Every stub of the exercise is a mutant here, marked "(the stub)".
"""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "07_imu_mechanisation"

_ATT = "C_next = so3.Exp(-w_mean * dt) @ C\n"
# attitude_step: R_nb in, R_nb out, through attitude_step_bn (cell att-nb)
_TO_C = "C = R.T"
_TO_R = "R_next = C_next.T"
_W = "w_mean = 0.5 * (w0 + w1) - b_w"
_A0 = "a0 = R0 @ (f0 - b_a) + g"
_A1 = "a1 = R1 @ (f1 - b_a) + g"
_ACC = _A0 + "\n    " + _A1
_VNEXT = "v_next = v + 0.5 * (a0 + a1) * dt"
_VEL = _ACC + "\n    " + _VNEXT
_VEL_STUB = "a_mean = 0.5 * (f0 + f1) - b_a + g\n    v_next = v + a_mean * dt"
_PNEXT = "p_next = p + 0.5 * (v0 + v1) * dt"
_DT = "dt = imu.t[k] - imu.t[k - 1]"
_ATT_CALL = "R[i] = attitude_step(R[i - 1], imu.angular_rate[k - 1], imu.angular_rate[k], zero, dt)"
_VEL_ARGS = "v[i - 1], R[i - 1], R[i], imu.specific_force[k - 1], imu.specific_force[k], zero, g, dt"
_POS_CALL = "p[i] = position_step(p[i - 1], v[i - 1], v[i], dt)"
_VEL_CALL = "v[i] = velocity_step(" + _VEL_ARGS + ")"
_STEP = _ATT_CALL + "\n        " + _VEL_CALL + "\n        " + _POS_CALL

# the challenge: level_attitude
_UP = "UP = np.array([0.0, 0.0, 1.0])"
_UPB = "up_body = f / np.linalg.norm(f)"
_AXIS = "axis = np.cross(up_body, UP)"
_GUARD = ("if sin_tilt == 0.0:  # level, or exactly upside down: no axis to normalise\n"
          "        return np.eye(3) if cos_tilt > 0.0 else np.diag([1.0, -1.0, -1.0])\n    ")
_RLEV = "R = so3.Exp(np.arctan2(sin_tilt, cos_tilt) * axis / sin_tilt)"
_LEVEL = ("up_body = f / np.linalg.norm(f)  # at rest f = −Rᵀg points up: this is up, in body coordinates\n"
          "    axis = np.cross(up_body, UP)  # perpendicular to both: turning about it tilts one onto the other\n"
          "    sin_tilt, cos_tilt = np.linalg.norm(axis), up_body @ UP\n    " + _GUARD + _RLEV)
_EULER = """roll = np.arctan2(f[1], f[2])
    pitch = np.arctan2(-f[0], np.hypot(f[1], f[2]))
    R = so3.Exp(pitch * np.array([0.0, 1.0, 0.0])) @ so3.Exp(roll * np.array([1.0, 0.0, 0.0]))"""

# Rodrigues' formula for the step's rotation backwards, Exp(−φ), applied to C on the left
_RODRIGUES = """phi = -w_mean * dt
    theta = np.linalg.norm(phi)
    K = so3.hat(phi)
    C_next = (np.eye(3) + np.sin(theta) / theta * K + (1 - np.cos(theta)) / theta**2 * K @ K) @ C
"""

_RODRIGUES_GUARDED = """phi = -w_mean * dt
    theta = np.linalg.norm(phi)
    K = so3.hat(phi)
    if theta < 1e-8:
        C_next = (np.eye(3) + K + 0.5 * K @ K) @ C
    else:
        C_next = (np.eye(3) + np.sin(theta) / theta * K + (1 - np.cos(theta)) / theta**2 * K @ K) @ C
"""
_SERIES = "C_next = (np.eye(3) + K + 0.5 * K @ K) @ C"

MUTANTS = [
    # --- attitude_step_bn: the step of C = R_bn = R_nbᵀ, derived from the lecture's --------
    Edit("attitude_step_bn", _ATT, "C_next = C\n", keyword="did not change",
         mistake="C left as it was (the stub)"),
    Edit("attitude_step_bn", _ATT, "C_next = C @ so3.Exp(w_mean * dt)\n", keyword="lecture 07's step for R",
         mistake="C Exp(ω̄T): the lecture's step for R_nb applied to C"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(w_mean * dt) @ C\n", keyword="transposed too",
         mistake="Exp(ω̄T) C: the order reversed, the rotation not transposed"),
    Edit("attitude_step_bn", _ATT, "C_next = C @ so3.Exp(-w_mean * dt)\n", keyword="reverses the order",
         mistake="C Exp(−ω̄T): the rotation transposed, the order kept"),
    Edit("attitude_step_bn", _ATT, "C_next = C.T @ so3.Exp(w_mean * dt)\n", keyword="returns the new R_nb",
         mistake="Cᵀ Exp(ω̄T): the new R_nb returned in place of C"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean * dt) @ C.T\n", keyword="do not transpose C",
         mistake="Exp(−ω̄T) Cᵀ"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(w_mean * dt) @ C.T\n",
         keyword="is the transpose of lecture 07's R_nb", mistake="Exp(φ) Cᵀ: no listed mistake, the fallback hint"),
    Edit("attitude_step_bn", _ATT, "C_next = (C @ so3.Exp(w_mean * dt)).T\n", keyword="do not transpose C",
         mistake="(C Exp(φ))ᵀ: the lecture's step on C, transposed"),
    Edit("attitude_step_bn", _W, "w_mean = 0.5 * (w0 + w1)", keyword="bias",
         mistake="gyro bias not subtracted"),
    Edit("attitude_step_bn", _W, "w_mean = 0.5 * (w0 + w1) + b_w", keyword="not added",
         mistake="gyro bias added"),
    Edit("attitude_step_bn", _W, "w_mean = 0.5 * (w0 + w1 - b_w)", keyword="not halved",
         mistake="gyro bias halved with the rates"),
    Edit("attitude_step_bn", _W, "w_mean = w0 - b_w", keyword="midpoint",
         mistake="Euler: the rate at the start of the step"),
    Edit("attitude_step_bn", _W, "w_mean = w1 - b_w", keyword="midpoint",
         mistake="the rate at the end of the step"),
    Edit("attitude_step_bn", _W, "w_mean = (w0 + w1) - b_w", keyword="half their sum",
         mistake="sum of the rates instead of their mean (the ½ missing)"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean) @ C\n", keyword="multiply by dt",
         mistake="rate used as a rotation vector (dt missing)"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean * dt**2) @ C\n", keyword="T²",
         mistake="φ = ω̄ T² instead of ω̄ T"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean * dt / 2) @ C\n", keyword="half of it",
         mistake="half the rotation of the step"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-np.deg2rad(w_mean) * dt) @ C\n", keyword="radians",
         mistake="rates converted from degrees although they are in rad/s"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-np.rad2deg(w_mean) * dt) @ C\n", keyword="radians",
         mistake="rates converted to degrees"),
    Edit("attitude_step_bn", _ATT, "C_next = (np.eye(3) - so3.hat(w_mean * dt)) @ C\n", keyword="first-order",
         mistake="first-order I − [φ]× (Ċ = −[ω]× C by Euler) without renormalising"),
    Edit("attitude_step_bn", _ATT, "C_next = C - so3.hat(w_mean) @ C * dt\n", keyword="first-order",
         mistake="Euler on Ċ = −[ω]× C"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.orthonormalise(np.eye(3) - so3.hat(w_mean * dt)) @ C\n",
         keyword="first-order", mistake="first-order I − [φ]×, re-orthonormalised"),
    Edit("attitude_step_bn", _ATT,
         "C_next = so3.quat_to_matrix(np.concatenate([[1.0], -0.5 * w_mean * dt])) @ C\n",
         keyword="first-order", mistake="first-order quaternion (1, −φ/2), normalised"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES, keyword="divides 0 by 0",
         mistake="own Rodrigues' formula without a small-angle branch (NaN at ω̄ = 0)"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("/ theta**2 * K @ K)", "/ theta * K @ K)"),
         keyword="rotation matrix", mistake="own Rodrigues' formula with (1 − cos θ)/θ instead of /θ²"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean) @ C * dt\n", keyword="rotation matrix",
         mistake="dt multiplied outside the exponential"),
    Edit("attitude_step_bn", _ATT,
         "C_next = so3.Exp(-0.5 * (w1 - b_w) * dt) @ so3.Exp(-0.5 * (w0 - b_w) * dt) @ C\n",
         keyword="two half-steps", mistake="two half-step rotations instead of one of the mean rate"),
    Edit("attitude_step_bn", _W, "w_mean = np.mean([w0, w1]) - b_w", keyword="axis 0",
         mistake="mean over all six numbers"),
    Edit("attitude_step_bn", _W, "w_mean = np.mean([w0, w1], axis=1) - b_w", keyword="axis 0",
         mistake="mean over the wrong axis (shape (2,))"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(-w_mean * dt)\n", keyword="previous attitude",
         mistake="the previous attitude forgotten"),

    # --- attitude_step: R_nb through attitude_step_bn ------------------------------------
    Edit("attitude_step", _TO_C, "C = R", cell="att-nb", keyword="not R itself",
         mistake="R handed to attitude_step_bn as if it were C (the stub of the first line)"),
    Edit("attitude_step", _TO_R, "R_next = C_next", cell="att-nb", keyword="transpose it back",
         mistake="C_next returned as R_next (the stub of the second line)"),
    Edit("attitude_step", "C_next = attitude_step_bn(C, w0, w1, b_w, dt)\n    # BEGIN SOLUTION attitude_step\n"
         "    R_next = C_next.T", "C_next = attitude_step_bn(R, w0, w1, b_w, dt)\n    # BEGIN SOLUTION attitude_step\n"
         "    R_next = C_next", cell="att-nb", keyword="and transpose what it returns",
         mistake="no conversion at all: R in, C out"),
    Edit("attitude_step", _ATT, "C_next = C @ so3.Exp(w_mean * dt)\n", cell="att",
         keyword="fix attitude_step_bn first", mistake="attitude_step_bn is the lecture's R step: blamed upstream"),
    Edit("attitude_step", _W, "w_mean = 0.5 * (w0 + w1)", cell="att", keyword="fix attitude_step_bn first",
         mistake="attitude_step_bn without the bias: blamed upstream"),

    # --- velocity_step (a whole step of three lines in the exercise) ---------------------
    Edit("velocity_step", _VEL, _VEL_STUB, keyword="body frame",
         mistake="the body-frame readings used as navigation-frame accelerations, not rotated (the stub)"),
    Edit("velocity_step", _ACC, _ACC.replace("+ g", "- g"), keyword="pointing down",
         mistake="the lecture's − g with the course's g = (0, 0, −9.81)"),
    Edit("velocity_step", _ACC, _ACC.replace(" + g", ""), keyword="gravity is missing",
         mistake="gravity left out"),
    Edit("velocity_step", _A1, "a1 = R1 @ (f1 - b_a)", keyword="in full",
         mistake="gravity added to one of the two accelerations only (½ g on the mean)"),
    Edit("velocity_step", _ACC, "a0 = R0 @ (f0 - b_a + g)\n    a1 = R1 @ (f1 - b_a + g)",
         keyword="navigation-frame", mistake="gravity added in the body frame, before rotating"),
    Edit("velocity_step", _ACC, "a0 = R0 @ f0 + g\n    a1 = R1 @ f1 + g", keyword="bias",
         mistake="accelerometer bias not subtracted"),
    Edit("velocity_step", _ACC, _ACC.replace("- b_a", "+ b_a"), keyword="not added",
         mistake="accelerometer bias added"),
    Edit("velocity_step", _ACC, "a0 = R0 @ f0 - b_a + g\n    a1 = R1 @ f1 - b_a + g", keyword="before rotating",
         mistake="bias subtracted in the navigation frame"),
    Edit("velocity_step", _A1, "a1 = R0 @ (f1 - b_a) + g", keyword="new attitude",
         mistake="the start-of-step attitude for the second reading"),
    Edit("velocity_step", _A0, "a0 = R1 @ (f0 - b_a) + g", keyword="old attitude",
         mistake="the end-of-step attitude for the first reading"),
    Edit("velocity_step", _ACC, "a0 = R1 @ (f0 - b_a) + g\n    a1 = R0 @ (f1 - b_a) + g", keyword="swapped",
         mistake="attitudes swapped between the two readings"),
    Edit("velocity_step", _VEL, "a_mean = R1 @ (0.5 * (f0 + f1) - b_a) + g\n    v_next = v + a_mean * dt",
         keyword="old attitude", mistake="the mean reading rotated with the end-of-step attitude"),
    Edit("velocity_step", _VEL, "a_mean = R0 @ (0.5 * (f0 + f1) - b_a) + g\n    v_next = v + a_mean * dt",
         keyword="new attitude", mistake="the mean reading rotated with the start-of-step attitude"),
    Edit("velocity_step", _VEL, "R_mid = R0 @ so3.Exp(0.5 * so3.Log(R0.T @ R1))\n"
         "    a_mean = R_mid @ (0.5 * (f0 + f1) - b_a) + g\n    v_next = v + a_mean * dt", keyword="mid-step",
         mistake="the mean reading rotated with the mid-step attitude"),
    Edit("velocity_step", _VEL, "a_mean = 0.5 * (R0 + R1) @ (0.5 * (f0 + f1) - b_a) + g\n"
         "    v_next = v + a_mean * dt", keyword="own time", mistake="mean attitude times mean reading"),
    Edit("velocity_step", _ACC, _ACC.replace("R0 @", "R0.T @").replace("R1 @", "R1.T @"), keyword="transpose",
         mistake="Rᵀ instead of R"),
    Edit("velocity_step", _VNEXT, "v_next = v + a0 * dt", keyword="Euler",
         mistake="Euler: the acceleration at the start of the step"),
    Edit("velocity_step", _VNEXT, "v_next = v + a1 * dt", keyword="midpoint",
         mistake="the acceleration at the end of the step"),
    Edit("velocity_step", _VNEXT, "v_next = v + (a0 + a1) * dt", keyword="half their sum",
         mistake="sum of the accelerations, gravity included twice (the ½ missing)"),
    Edit("velocity_step", _VEL, "a0 = R0 @ (f0 - b_a)\n    a1 = R1 @ (f1 - b_a)\n"
         "    v_next = v + 0.5 * (a0 + a1) * dt + g", keyword="g T", mistake="gravity not multiplied by dt"),
    Edit("velocity_step", _A1, "a1 = R1 @ f1 + g", keyword="not from one only",
         mistake="bias subtracted from the first reading only"),
    Edit("velocity_step", _ACC, _ACC.replace("+ g", "+ np.array([0.0, 0.0, -9.81])"), keyword="hard-coded",
         mistake="gravity hard-coded instead of the g handed in"),
    Edit("velocity_step", _VNEXT, "v_next = v + 0.5 * (a0 + a1) * dt**2", keyword="T²",
         mistake="T² instead of T"),
    Edit("velocity_step", _VNEXT, "v_next = v + 0.5 * (a0 + a1)", keyword="multiply the acceleration",
         mistake="dt missing"),
    Edit("velocity_step", _VNEXT, "v_next = v + 0.5 * (a0 + a1) * dt / 2", keyword="whole step",
         mistake="half the step"),
    Edit("velocity_step", _VNEXT, "v_next = 0.5 * (a0 + a1) * dt", keyword="previous velocity",
         mistake="the increment returned instead of the new velocity"),

    # --- position_step -------------------------------------------------------------------
    Edit("position_step", _PNEXT, "p_next = p + v1 * dt", keyword="not the new one",
         mistake="the new velocity only"),
    Edit("position_step", _PNEXT, "p_next = p + v0 * dt", keyword="Euler",
         mistake="Euler: the old velocity only"),
    Edit("position_step", _PNEXT, "p_next = p + (v0 + v1) * dt", keyword="½ is missing",
         mistake="the ½ missing"),
    Edit("position_step", _PNEXT, "p_next = p + 0.5 * (v0 + v1) * dt**2", keyword="T²",
         mistake="T² instead of T"),
    Edit("position_step", _PNEXT, "p_next = p + 0.5 * (v0 + v1)", keyword="multiply the mean velocity",
         mistake="dt missing"),
    Edit("position_step", _PNEXT, "p_next = p + v0 * dt + 0.5 * (v1 - v0) * dt**2", keyword="units",
         mistake="½ a T² with the velocity change in place of the acceleration: m·s, not m (the stub)"),
    Edit("position_step", _PNEXT, "p_next = p + 0.5 * (v1 - v0) * dt", keyword="sign",
         mistake="difference of the velocities instead of their sum"),
    Edit("position_step", _PNEXT, "p_next = 0.5 * (v0 + v1) * dt", keyword="previous position",
         mistake="the displacement returned instead of the new position"),
    Edit("position_step", _PNEXT, "p_next = p + np.mean([v0, v1]) * dt", keyword="axis 0",
         mistake="mean over all entries instead of over the two velocities"),
    Edit("position_step", _PNEXT, "p_next = p + np.mean([v0, v1], axis=1) * dt", keyword="axis 0",
         mistake="mean over the wrong axis (shape (2,))"),

    # --- mechanisation_run ---------------------------------------------------------------
    Edit("mechanisation_run", _DT, "dt = imu.t[1] - imu.t[0]", keyword="irregular",
         mistake="one constant dt (the exercise's stub)"),
    Edit("mechanisation_run", _DT, "dt = imu.t[start + 1] - imu.t[start]", keyword="irregular",
         mistake="the slice's first interval for every step"),
    Edit("mechanisation_run", _DT, "dt = imu.t[k + 1] - imu.t[k]", keyword="off by one",
         mistake="dt of the next interval"),
    Edit("mechanisation_run", _ATT_CALL,
         "R[i] = attitude_step(R[i - 1], imu.angular_rate[k], imu.angular_rate[k + 1], zero, dt)",
         keyword="off by one", mistake="rates one sample late"),
    Edit("mechanisation_run", "imu.specific_force[k - 1], imu.specific_force[k], zero",
         "imu.specific_force[k - 2], imu.specific_force[k - 1], zero", keyword="off by one",
         mistake="specific forces one sample early"),
    Edit("mechanisation_run", "k = start + i", "k = i", keyword="start + i",
         mistake="the slice's start ignored"),
    Edit("mechanisation_run", _VEL_ARGS, _VEL_ARGS.replace("R[i - 1], R[i]", "R[i - 1], R[i - 1]"),
         keyword="old attitude twice", mistake="the old attitude handed to the velocity step twice"),
    Edit("mechanisation_run", _VEL_ARGS, _VEL_ARGS.replace("R[i - 1], R[i]", "R[i], R[i]"),
         keyword="new attitude twice", mistake="the new attitude handed to the velocity step twice"),
    Edit("mechanisation_run", _VEL_ARGS, _VEL_ARGS.replace("R[i - 1], R[i]", "R[i], R[i - 1]"),
         keyword="swapped", mistake="the attitudes handed to the velocity step in the wrong order"),
    Edit("mechanisation_run", _ATT_CALL, _ATT_CALL.replace("imu.angular_rate[k]", "imu.angular_rate[k - 1]"),
         keyword="one reading twice", mistake="the rate at k−1 twice (Euler)"),
    Edit("mechanisation_run", "imu.specific_force[k - 1], imu.specific_force[k], zero",
         "imu.specific_force[k], imu.specific_force[k], zero", keyword="one reading twice",
         mistake="the specific force at k twice"),
    Edit("mechanisation_run", _DT, "dt = imu.t[k] - imu.t[start]", keyword="time since the start",
         mistake="dt measured from the start of the run"),
    Edit("mechanisation_run", _ATT_CALL, _ATT_CALL.replace("attitude_step(R[i - 1]", "attitude_step(state.rotation"),
         keyword="previous row", mistake="every attitude step from the initial attitude"),
    Edit("mechanisation_run", _POS_CALL, "p[i] = position_step(p[i - 1], v[i - 1], v[i - 1], dt)",
         keyword="old velocity twice", mistake="the old velocity handed to the position step twice"),
    Edit("mechanisation_run", _ATT_CALL, "R[i] = R[i - 1]", keyword="never updated",
         mistake="the attitude not propagated"),
    Edit("mechanisation_run", "zero, g, dt)", "g, zero, dt)", keyword="swapped",
         mistake="gravity and the accelerometer bias swapped in the call"),
    Edit("mechanisation_run", "zero, g, dt)", "zero, zero, dt)", keyword="gravity is missing",
         mistake="zero gravity handed to the velocity step"),
    Edit("mechanisation_run", "for i in range(1, n):", "for i in range(1, n - 1):", keyword="last state",
         mistake="the loop stops one step early"),
    Edit("mechanisation_run", "for i in range(1, n):", "for i in range(n):", keyword="initial state",
         mistake="the loop starts at 0 and overwrites the initial state"),
    Edit("mechanisation_run", "p[0], v[0], R[0] = state.position, state.velocity, state.rotation",
         "p[0], v[0], R[0] = state.velocity, state.position, state.rotation", keyword="initial state",
         mistake="position and velocity swapped in the first row"),
    Edit("mechanisation_run", "return p, v, R", "return p, R, v", keyword="in this order",
         mistake="results returned in the wrong order"),
    Edit("mechanisation_run", "return p, v, R", "return p, v, R.transpose(0, 2, 1)", keyword="transposed",
         mistake="rotations returned transposed"),
    # the loop's body, a whole step of three lines in the exercise
    Edit("mechanisation_run", _STEP, "p[i], v[i], R[i] = p[i - 1], v[i - 1], R[i - 1]", keyword="no step",
         mistake="the loop body's placeholder: every row a copy of the one before (the stub)"),
    Edit("mechanisation_run", _STEP, _VEL_CALL + "\n        " + _ATT_CALL + "\n        " + _POS_CALL,
         keyword="used before it is filled", mistake="the velocity step before the attitude step (R[i] still NaN)"),
    Edit("mechanisation_run", _STEP, _ATT_CALL + "\n        " + _POS_CALL + "\n        " + _VEL_CALL,
         keyword="used before it is filled", mistake="the position step before the velocity step (v[i] still NaN)"),
    Edit("mechanisation_run", _POS_CALL, "p[i] = p[i - 1]", keyword="positions on",
         mistake="the position not propagated"),
    Edit("mechanisation_run", _VEL_CALL, "v[i] = v[i - 1]", keyword="never change",
         mistake="the velocity not propagated"),
    # a correct mechanise with a wrong step function: the hint must blame the step
    Edit("mechanisation_run", _ATT, "C_next = C @ so3.Exp(w_mean * dt)\n", cell="att",
         keyword="fix attitude_step_bn first", mistake="attitude_step_bn is the lecture's R step (two levels up)"),
    Edit("mechanisation_run", _TO_R, "R_next = C_next", cell="att-nb",
         keyword="fix attitude_step first", mistake="attitude_step returns C_next"),
    Edit("mechanisation_run", _ACC, _ACC.replace("+ g", "- g"), cell="vel",
         keyword="fix velocity_step first", mistake="velocity_step with the wrong gravity sign"),
    Edit("mechanisation_run", _PNEXT, "p_next = p + v0 * dt", cell="pos",
         keyword="fix position_step first", mistake="position_step with Euler's rule"),

    # --- the sweep of the singular regimes (issue 25): small-angle switches and series ------
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "theta < 1e-9").replace(
        _SERIES, "C_next = C"), keyword="small rotations",
         mistake="below 1e-9 rad the step returns C unchanged (error |φ| up to 1e-9, 10× the tolerance)"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "np.linalg.norm(w_mean) < 1e-9").replace(
        _SERIES, "C_next = C.copy()"), keyword="small rotations",
         mistake="the switch on the rate, not the angle: below 1e-9 rad/s C unchanged (0.5 s steps turn 5e-10 rad)"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "theta < 1e-3").replace(
        _SERIES, "C_next = (np.eye(3) + K) @ C"), keyword="first-order",
         mistake="the first-order I + [φ]× below 1e-3 rad (error ½|φ|² up to 5e-7; not a rotation)"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "theta < 3e-3"),
         keyword="truncated series", mistake="the second-order series kept up to 3e-3 rad (error |φ|³/6 up to 4.5e-9)"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "np.max(phi) < 1e-8"),
         keyword="truncated series", mistake="the switch on the largest component, not the norm (every rotation "
                                             "about an all-negative axis takes the series)"),
    Edit("attitude_step_bn", _ATT, "theta = np.linalg.norm(w_mean * dt) % (2 * np.pi)\n"
         "    axis = w_mean / max(np.linalg.norm(w_mean), 1e-300)\n"
         "    C_next = so3.Exp(-min(theta, 2 * np.pi - theta) * axis) @ C\n", keyword="large rotation",
         mistake="the angle folded into [0, π] without turning the axis round (wrong beyond π)"),
    # --- behaviour: arguments changed in place, single precision (issue 25) -----------------
    Edit("attitude_step_bn", _ATT, "C[:] = so3.Exp(-w_mean * dt) @ C\n    C_next = C.copy()\n", keyword="in place",
         mistake="the new attitude written into the caller's C"),
    Edit("attitude_step_bn", _ATT, "C[...] = so3.Exp(-w_mean * dt) @ C\n    C_next = C\n", keyword="in place",
         mistake="the caller's C turned in place, and returned"),
    Edit("attitude_step_bn", _W, "w0 += w1\n    w0 *= 0.5\n    w_mean = w0 - b_w", keyword="in place",
         mistake="the mean rate accumulated into the caller's w0"),
    Edit("attitude_step_bn", _ATT, "C_next = (so3.Exp(-w_mean * dt) @ C).astype(np.float32)\n",
         keyword="single precision", mistake="the attitude in float32"),
    Edit("attitude_step", _TO_R, "R_next = C_next.T.astype(np.float32)", cell="att-nb",
         keyword="single precision", mistake="R_next in float32"),
    # (the first case is an IMU at rest, whose increment is zero: there v comes back unchanged but
    # is the caller's own array, which is named first)
    Edit("velocity_step", _VNEXT, "v += 0.5 * (a0 + a1) * dt\n    v_next = v", keyword="argument v",
         mistake="the increment added into the caller's v (v += ...)"),
    Edit("velocity_step", _VNEXT, "v += 0.5 * (a0 + a1) * dt\n    v_next = v.copy()", keyword="in place",
         mistake="the increment added into the caller's v, a copy returned"),
    Edit("velocity_step", _A0, "f0 -= b_a\n    a0 = R0 @ f0 + g", keyword="in place",
         mistake="the bias subtracted into the caller's reading f0"),
    Edit("velocity_step", _VNEXT, "v_next = (v + 0.5 * (a0 + a1) * dt).astype(np.float32)",
         keyword="single precision", mistake="the velocity in float32"),
    Edit("position_step", _PNEXT, "p += 0.5 * (v0 + v1) * dt\n    p_next = p", keyword="in place",
         mistake="the displacement added into the caller's p (p += ...)"),
    Edit("position_step", _PNEXT, "p_next = np.asarray(p + 0.5 * (v0 + v1) * dt, dtype=np.float32)",
         keyword="single precision", mistake="the position in float32"),
    Edit("level_attitude", _RLEV, _RLEV + ".astype(np.float32)", keyword="single precision",
         mistake="the levelled attitude in float32"),
    Edit("mechanisation_run", "p, v, R = np.full((n, 3), np.nan), np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan)",
         "p, v, R = (np.full((n, 3), np.nan, dtype=np.float32), np.full((n, 3), np.nan),\n"
         "               np.full((n, 3, 3), np.nan))", keyword="single precision", mistake="positions stored in float32"),
    # a correct loop whose velocity_step adds into v: row i − 1 changes under it (v[i − 1] is a view)
    Edit("mechanisation_run", _VNEXT, "v += 0.5 * (a0 + a1) * dt\n    v_next = v", cell="vel",
         keyword="fix velocity_step first", mistake="velocity_step adds into the caller's v"),
    Edit("mechanisation_run", _PNEXT, "p += 0.5 * (v0 + v1) * dt\n    p_next = p", cell="pos",
         keyword="fix position_step first", mistake="position_step adds into the caller's p"),

    # --- level_attitude (the optional challenge) ------------------------------------------
    Edit("level_attitude", _LEVEL, "R = np.eye(3)", keyword="identity",
         mistake="the identity: the IMU assumed level (the stub)"),
    Edit("level_attitude", _RLEV, _RLEV + ".T", keyword="transposed", mistake="R_bn instead of R_nb"),
    Edit("level_attitude", _AXIS, "axis = np.cross(UP, up_body)", keyword="transposed",
         mistake="the cross product in the other order: the rotation turns up onto f"),
    Edit("level_attitude", _UP, "UP = np.array([0.0, 0.0, -1.0])", keyword="points up",
         mistake="f turned onto the direction of gravity (down)"),
    Edit("level_attitude", _UPB, "up_body = -f / np.linalg.norm(f)", keyword="points up",
         mistake="−f taken as up (the specific force thought to point along gravity)"),
    Edit("level_attitude", _RLEV, "R = so3.Exp(np.arcsin(sin_tilt) * axis / sin_tilt)", keyword="quadrant",
         mistake="the tilt from arcsin: 180° − θ beyond 90°"),
    Edit("level_attitude", _RLEV, "R = so3.Exp(axis)", keyword="sin θ, not θ",
         mistake="the cross product used as the rotation vector"),
    Edit("level_attitude", _RLEV, "R = so3.Exp(np.arctan2(sin_tilt, cos_tilt) * axis)", keyword="normalise it",
         mistake="the axis not normalised"),
    Edit("level_attitude", _RLEV, "R = so3.Exp(np.degrees(np.arctan2(sin_tilt, cos_tilt)) * axis / sin_tilt)",
         keyword="radians", mistake="the tilt in degrees"),
    Edit("level_attitude", _GUARD, "", keyword="divides 0 by 0", mistake="no branch for a level IMU (0/0)"),
    Edit("level_attitude", _LEVEL, "axis = np.cross(f, UP)\n    if np.linalg.norm(axis) == 0.0:\n"
         "        return np.eye(3)\n    R = so3.Exp(np.arccos(f @ UP) * axis / np.linalg.norm(axis))",
         keyword="unit vectors", mistake="arccos of f · up with f not normalised (NaN)"),
    Edit("level_attitude", _RLEV, "R = np.eye(3) + so3.hat(np.arctan2(sin_tilt, cos_tilt) * axis / sin_tilt)",
         keyword="not a rotation matrix", mistake="the first-order I + [φ]× instead of Exp"),
    Edit("level_attitude", _LEVEL, _EULER.replace("np.arctan2(f[1], f[2])", "np.arctan(f[1] / f[2])"),
         keyword="quadrant", mistake="roll and pitch with arctan(y/x): wrong beyond 90° of tilt"),
    # f × up = 0 when the IMU is exactly upside down too: a guard for the level IMU alone
    Edit("level_attitude", _GUARD, "if sin_tilt == 0.0:  # level: no axis to normalise\n        return np.eye(3)\n    ",
         keyword="exactly upside down", mistake="the identity wherever f × up = 0, upside down too"),
    Edit("level_attitude", _GUARD, "if sin_tilt == 0.0:\n"
         "        return np.eye(3) if cos_tilt > 0.0 else np.diag([1.0, 1.0, -1.0])\n    ",
         keyword="exactly upside down", mistake="z flipped alone upside down: a reflection, not a rotation"),
    Edit("level_attitude", _LEVEL, "up_body = f / np.linalg.norm(f)\n"
         "    q = np.concatenate([[1.0 + up_body @ UP], np.cross(up_body, UP)])\n"
         "    R = so3.quat_to_matrix(q / np.linalg.norm(q))",
         keyword="exactly upside down", mistake="the half-angle quaternion (1 + u·up, u × up): 0/0 upside down"),
]

EQUIVALENTS = [
    # attitude_step_bn: tolerance ATOL 1e-10 (imu.ATTITUDE_ATOL), on C's step transposed back:
    # every exact evaluation of Exp agrees to ~1e-15, while the closest mistake (a
    # re-orthonormalised first-order form) errs by ~3e-6 on the "tumbling" case
    Edit("attitude_step_bn", _ATT, "C_next = so3.Exp(w_mean * dt).T @ C\n", mistake="Exp(φ)ᵀ C"),
    Edit("attitude_step_bn", _ATT, "C_next = (C.T @ so3.Exp(w_mean * dt)).T\n",
         mistake="the lecture's step of R = Cᵀ, transposed back"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED,
         mistake="Rodrigues' formula of −φ with a second-order series below 1e-8 rad"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.exp(-w_mean * dt) @ C\n", mistake="so3.exp instead of so3.Exp"),
    Edit("attitude_step_bn", _ATT, _RODRIGUES_GUARDED.replace("theta < 1e-8", "theta < 1e-4"),
         mistake="Rodrigues with the second-order series below 1e-4 rad (error θ³/6 ≤ 2e-13)"),
    Edit("attitude_step_bn", _ATT, "q = so3.quat_multiply(so3.quat_exp(-w_mean * dt), so3.matrix_to_quat(C))\n"
         "    C_next = so3.quat_to_matrix(q)\n", mistake="the attitude kept as a quaternion, q{−φ} ⊗ q"),
    Edit("attitude_step_bn", _ATT, "C_next = so3.quat_to_matrix(so3.quat_exp(-w_mean * dt)) @ C\n",
         mistake="via a unit quaternion"),
    Edit("attitude_step_bn", _ATT, "from scipy.linalg import expm\n    C_next = expm(-so3.hat(w_mean * dt)) @ C\n",
         mistake="matrix exponential of the skew matrix"),
    Edit("attitude_step_bn", _ATT, "from scipy.spatial.transform import Rotation\n"
         "    C_next = Rotation.from_rotvec(w_mean * dt).inv().as_matrix() @ C\n", mistake="scipy's Rotation, inverted"),
    Edit("attitude_step_bn", _ATT, "C_next = (so3.Exp(-w_mean * dt) @ C).tolist()\n", mistake="a nested list"),
    Edit("attitude_step_bn", _W, "w_mean = 0.5 * ((w0 - b_w) + (w1 - b_w))",
         mistake="the lecture's mean of the bias-corrected rates"),
    Edit("attitude_step_bn", _W, "w_mean = (w0 + w1) / 2 - b_w", mistake="/ 2 instead of 0.5 *"),
    # attitude_step: R_nb through attitude_step_bn, or written directly from the lecture
    Edit("attitude_step", _TO_C, "C = np.transpose(R)", cell="att-nb", mistake="np.transpose"),
    Edit("attitude_step", _TO_R, "R_next = np.array(C_next).T.copy()", cell="att-nb", mistake="a transposed copy"),
    Edit("attitude_step", _TO_R, "R_next = R @ so3.Exp((0.5 * (w0 + w1) - b_w) * dt)", cell="att-nb",
         mistake="the lecture's step for R written directly (attitude_step_bn's result unused)"),
    # velocity_step: ATOL 1e-10 m/s (imu.VELOCITY_ATOL): any order of operations rounds to
    # ~1e-14 m/s; every listed mistake changes v by ≥ 2e-3 m/s on some case
    Edit("velocity_step", _VEL, "specific = 0.5 * (R0 @ (f0 - b_a) + R1 @ (f1 - b_a))\n"
         "    v_next = v + (specific + g) * dt", mistake="the mean rotated specific force, then g"),
    Edit("velocity_step", _VEL, "a0 = R0 @ f0 - R0 @ b_a + g\n    a1 = R1 @ f1 - R1 @ b_a + g\n    " + _VNEXT,
         mistake="bias term expanded"),
    Edit("velocity_step", _VNEXT, "v_next = v + np.mean([a0, a1], axis=0) * dt",
         mistake="np.mean over the two accelerations"),
    Edit("velocity_step", _ACC, "a0 = np.einsum('ij,j->i', R0, f0 - b_a) + g\n"
         "    a1 = np.einsum('ij,j->i', R1, f1 - b_a) + g", mistake="einsum"),
    Edit("velocity_step", _VEL, "a0 = R0 @ (f0 - b_a)\n    a1 = R1 @ (f1 - b_a)\n"
         "    v_next = v + 0.5 * (a0 + a1) * dt + g * dt", mistake="g T as its own term"),
    Edit("velocity_step", _ACC, "g_up = -g\n    " + _ACC.replace("+ g", "- g_up"),
         mistake="the lecture's − g with g pointing up"),
    Edit("velocity_step", _VEL, "readings = np.array([f0, f1]) - b_a\n"
         "    a = np.einsum('kij,kj->ki', np.array([R0, R1]), readings) + g\n"
         "    v_next = v + a.mean(axis=0) * dt", mistake="both readings rotated at once"),
    Edit("velocity_step", _VNEXT, "v_next = list(v + 0.5 * (a0 + a1) * dt)", mistake="a list"),
    # position_step: ATOL 1e-9 m (imu.POSITION_ATOL): round-off ~1e-13 m; mistakes ≥ 0.2 m
    Edit("position_step", _PNEXT, "p_next = p + v0 * dt + 0.5 * (v1 - v0) * dt",
         mistake="p + v₀T + ½(v₁ − v₀)T"),
    Edit("position_step", _PNEXT, "a = (v1 - v0) / dt\n    p_next = p + v0 * dt + 0.5 * a * dt**2",
         mistake="p + v₀T + ½aT² with a = (v₁ − v₀)/T (the core's form)"),
    Edit("position_step", _PNEXT, "p_next = p + (v0 + v1) * dt / 2", mistake="/ 2"),
    Edit("position_step", _PNEXT, "p_next = p + np.mean([v0, v1], axis=0) * dt", mistake="np.mean axis 0"),
    Edit("position_step", _PNEXT, "p_next = tuple(p + 0.5 * (v0 + v1) * dt)", mistake="a tuple"),
    # mechanisation_run: ATOL 1e-6 m, 1e-8 m/s, 1e-10 (imu.RUN_ATOL): a loop and the vectorised
    # reference round differently by ~1e-13 over 500 steps; every loop mistake is ≥ 4e-4 m
    Edit("mechanisation_run", _DT, "dt = np.diff(imu.t[k - 1:k + 1])[0]", mistake="dt by np.diff"),
    Edit("mechanisation_run", "for i in range(1, n):\n        k = start + i",
         "for k in range(start + 1, stop):\n        i = k - start", mistake="loop over k instead of i"),
    Edit("mechanisation_run", "return p, v, R", "return [p, v, R]", mistake="a list of the three arrays"),
    Edit("mechanisation_run", _ATT_CALL,
         "R[i] = R[i - 1] @ so3.Exp((0.5 * (imu.angular_rate[k - 1] + imu.angular_rate[k])) * dt)",
         mistake="the attitude step written inline"),
    Edit("mechanisation_run", _STEP,
         "R_new = attitude_step(R[i - 1], imu.angular_rate[k - 1], imu.angular_rate[k], zero, dt)\n"
         "        v_new = velocity_step(v[i - 1], R[i - 1], R_new, imu.specific_force[k - 1], "
         "imu.specific_force[k], zero, g, dt)\n"
         "        p[i], v[i], R[i] = position_step(p[i - 1], v[i - 1], v_new, dt), v_new, R_new",
         mistake="the step into local names, then one assignment of the row"),
    # level_attitude: R f/|f| against up, ATOL 1e-9 (imu.LEVEL_ATOL): every exact construction
    # agrees to ~1e-15 and arccos to 1e-10 (tilt 1e-6 rad); the listed mistakes are ≥ 0.05 rad off
    Edit("level_attitude", _RLEV, "R = so3.Exp(np.arccos(cos_tilt) * axis / sin_tilt)",
         mistake="the tilt from arccos of the cosine"),
    Edit("level_attitude", _LEVEL, _EULER, mistake="roll and pitch (atan2), heading zero"),
    Edit("level_attitude", _LEVEL, "from scipy.spatial.transform import Rotation\n"
         "    R = Rotation.align_vectors([UP], [f])[0].as_matrix()", mistake="scipy's align_vectors"),
    Edit("level_attitude", _LEVEL, "third = f / np.linalg.norm(f)\n"
         "    first = np.cross([0.0, 1.0, 0.0], third)\n"
         "    first = first / np.linalg.norm(first)\n"
         "    R = np.array([first, np.cross(third, first), third])",
         mistake="the rows of R_nb built as the navigation axes in body coordinates"),
    Edit("level_attitude", _RLEV, "R = so3.Exp(np.arctan2(sin_tilt, cos_tilt) * axis / sin_tilt)\n"
         "    R = so3.Exp(1.3 * UP) @ R", mistake="any heading: a turn about up after levelling"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("attitude_step_bn", _W, "w_mean = 0.5 * (w1 + w0) - b_w",
               reason="floating-point addition commutes exactly: the two rates in either order"),
    Equivalent("velocity_step", _A0, "a0 = g + R0 @ (f0 - b_a)",
               reason="floating-point addition commutes exactly"),
    Equivalent("velocity_step", _VNEXT, "v_next = v + 0.5 * (a1 + a0) * dt",
               reason="floating-point addition commutes exactly: the lecture's order of the two"),
    Equivalent("position_step", _PNEXT, "p_next = p + 0.5 * (v1 + v0) * dt",
               reason="floating-point addition commutes exactly: the two velocities in either order"),
    Equivalent("mechanisation_run", _POS_CALL, "p[i] = position_step(p[i - 1], v[i], v[i - 1], dt)",
               reason="position_step is symmetric in v0 and v1 (it uses their sum)"),
]
