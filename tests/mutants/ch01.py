"""Chapter 01 (Bayes' rule, the histogram filter): plausible mistakes in the exercise's functions.

The solution's cells: ``likelihood`` (sensor_likelihood), ``update`` (histogram_update),
``predict`` (histogram_predict), ``run`` (run_histogram_filter, which calls the other three)
and ``challenge`` (circular_motion_model, the optional challenge).
"""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "01_bayes_rule"

_LIK = "return np.where(world == z, p_correct, 1.0 - p_correct)"
_UPD = "posterior = unnormalised / unnormalised.sum()"
_PRED = "return transition @ belief"
_RUN = "belief = histogram_update(belief, likelihood)"
# the recursion's fix region: the whole step between the likelihood and the append
_STEP = ("if k > 0:\n"
         "            belief = histogram_predict(belief, transition)\n"
         "        belief = histogram_update(belief, likelihood)")
_STUB_END = ("        # STUB\n"
             "        # # fix this: the robot moves between two readings, and each step must start from\n"
             "        # # what the earlier readings taught\n"
             "        # belief = histogram_update(belief0, likelihood)\n"
             "        # END SOLUTION\n")
_LOOP = ("for k, z in enumerate(measurements):\n"
         "        likelihood = sensor_likelihood(world, z, p_correct)\n"
         "        # BEGIN SOLUTION histogram_filter\n"
         "        " + _STEP + "\n" + _STUB_END +
         "        beliefs.append(belief)")
_STORE = _RUN + "\n" + _STUB_END + "        beliefs.append(belief)"
# the update's fix region: the whole of Bayes' rule
_BAYES = "unnormalised = likelihood * belief\n    " + _UPD
# the challenge's fix region: the inner loop over the cells
_RING = ("for j in range(n):                              # from cell j ...\n"
         "            transition[(j + offset) % n, j] += prob     # ... to cell j + offset, round the ring")

MUTANTS = [
    # --- door_likelihood: sensor_likelihood(world, z, p_correct) --------------------------
    Edit("door_likelihood", _LIK, "return np.where(world == z, 1.0 - p_correct, p_correct)",
         keyword="swapped", mistake="p_correct and 1 - p_correct swapped"),
    Edit("door_likelihood", _LIK, "return np.where(world != z, p_correct, 1.0 - p_correct)",
         keyword="swapped", mistake="comparison negated (world != z)"),
    Edit("door_likelihood", _LIK, "return np.where(world == z, 1.0, 0.0)",
         keyword="not 1 and 0", mistake="a perfect sensor (1 and 0)"),
    Edit("door_likelihood", _LIK, "return np.where(world == z, p_correct, 0.0)",
         keyword="not impossible", mistake="a disagreeing cell gets 0 instead of 1 - p_correct"),
    Edit("door_likelihood", _LIK, "return np.where(world == 1, p_correct, 1.0 - p_correct)",
         keyword="depend on z", mistake="compares the map with 1 (a door) instead of with z"),
    Edit("door_likelihood", _LIK, "return np.where(world, p_correct, 1.0 - p_correct)",
         keyword="depend on z", mistake="uses the map as the condition, z ignored"),
    Edit("door_likelihood", _LIK, "return np.where(world == z, 0.9, 0.1)",
         keyword="p_correct", mistake="p_correct hard-coded as 0.9"),
    Edit("door_likelihood", _LIK,
         "lik = np.where(world == z, p_correct, 1.0 - p_correct)\n    return lik / lik.sum()",
         keyword="do not normalise", mistake="likelihood normalised over the cells"),
    Edit("door_likelihood", _LIK, "return np.where(CORRIDOR == z, p_correct, 1.0 - p_correct)",
         keyword="length from the world argument", mistake="the global CORRIDOR instead of world"),
    Edit("door_likelihood", _LIK, "return p_correct if world[0] == z else 1.0 - p_correct",
         keyword="one entry per cell", mistake="a single number instead of one value per cell"),
    Edit("door_likelihood", _LIK, "return np.where(world == z, p_correct, p_correct - 1.0)",
         keyword="negative", mistake="1 - p_correct written as p_correct - 1"),

    # --- histogram_update: histogram_update(belief, likelihood) --------------------------
    Edit("histogram_update", _UPD, "posterior = unnormalised",
         keyword="evidence", mistake="not normalised"),
    Edit("histogram_update", _UPD, "posterior = unnormalised / unnormalised.max()",
         keyword="evidence", mistake="normalised by the maximum"),
    Edit("histogram_update", _UPD, "posterior = unnormalised / belief.sum()",
         keyword="evidence", mistake="divided by the prior's sum (1)"),
    Edit("histogram_update", _UPD, "posterior = unnormalised / likelihood.sum()",
         keyword="evidence", mistake="divided by the likelihood's sum"),
    Edit("histogram_update", _UPD, "posterior = unnormalised / unnormalised.mean()",
         keyword="evidence", mistake="divided by the mean instead of the sum"),
    Edit("histogram_update", "unnormalised = likelihood * belief", "unnormalised = likelihood + belief",
         keyword="does not add", mistake="prior and likelihood added"),
    Edit("histogram_update", "unnormalised = likelihood * belief", "unnormalised = likelihood",
         keyword="prior is missing", mistake="prior left out"),
    Edit("histogram_update", "unnormalised = likelihood * belief", "unnormalised = belief",
         keyword="likelihood is missing", mistake="likelihood left out (posterior = prior)"),
    Edit("histogram_update", "unnormalised = likelihood * belief", "unnormalised = likelihood / belief",
         keyword="divided", mistake="likelihood divided by the prior"),
    Edit("histogram_update", "unnormalised = likelihood * belief", "unnormalised = likelihood @ belief",
         keyword="element-wise", mistake="dot product (the evidence) instead of the element-wise product"),
    Edit("histogram_update", "unnormalised = likelihood * belief",
         "unnormalised = likelihood ** 2 * belief",
         keyword="twice", mistake="likelihood applied twice"),

    # --- histogram_predict: histogram_predict(belief, transition) ------------------------
    Edit("histogram_predict", _PRED, "return transition.T @ belief",
         keyword="transposed", mistake="transition.T @ belief"),
    Edit("histogram_predict", _PRED, "return belief @ transition",
         keyword="transposed", mistake="belief @ transition, the row-vector convention (the stub)"),
    Edit("histogram_predict", _PRED, "return (transition * belief).sum(axis=0)",
         keyword="wrong axis", mistake="element-wise product summed over i (axis 0)"),
    Edit("histogram_predict", _PRED, "return (transition * belief[:, None]).sum(axis=0)",
         keyword="axis 0", mistake="belief broadcast along rows, summed over axis 0 (a transpose)"),
    Edit("histogram_predict", _PRED, "return (transition * belief[:, None]).sum(axis=1)",
         keyword="wrong axis", mistake="belief broadcast along rows, summed over axis 1"),
    Edit("histogram_predict", _PRED, "return belief",
         keyword="motion model was not applied", mistake="no prediction"),
    Edit("histogram_predict", _PRED, "return transition * belief",
         keyword="element-wise", mistake="element-wise product without the sum"),
    Edit("histogram_predict", _PRED, "return transition @ transition @ belief",
         keyword="twice", mistake="motion applied twice"),
    Edit("histogram_predict", _PRED, "return np.roll(belief, 1)",
         keyword="shifted", mistake="a deterministic shift by one cell"),
    Edit("histogram_predict", _PRED, "return np.roll(belief, -1)",
         keyword="shifted", mistake="a deterministic shift back by one cell"),
    Edit("histogram_predict", _PRED, "return np.linalg.solve(transition, belief)",
         keyword="inverted", mistake="the motion model inverted"),
    Edit("histogram_predict", _PRED,
         "out = transition.T @ belief\n    return out / out.sum()",
         keyword="transposed", mistake="transposed, then normalised to hide it"),
    Edit("histogram_predict", _PRED,
         "out = np.zeros(len(belief))\n    for i in range(len(belief)):\n"
         "        for j in range(len(belief)):\n            out[i] += transition[j, i] * belief[j]\n"
         "    return out",
         keyword="transposed", mistake="a double loop with transition[j, i]"),

    # --- histogram_filter: run_histogram_filter(...) -------------------------------------
    Edit("histogram_filter", _RUN, "belief = histogram_update(belief0, likelihood)",
         keyword="restarts from belief0",
         mistake="each update starts from belief0 (the prediction computed, then dropped)"),
    Edit("histogram_filter", "belief = histogram_predict(belief, transition)",
         "belief = histogram_predict(belief0, transition)",
         keyword="from belief0", mistake="each step predicts from belief0"),
    Edit("histogram_filter", "belief = histogram_predict(belief, transition)",
         "histogram_predict(belief, transition)",
         keyword="prediction step is missing", mistake="prediction computed but not assigned"),
    Edit("histogram_filter", "if k > 0:", "if k >= 0:",
         keyword="before the first measurement", mistake="a prediction at step 0"),
    Edit("histogram_filter", _STORE,
         "beliefs.append(belief)\n        belief = histogram_update(belief, likelihood)",
         keyword="stored the prior", mistake="the prior stored instead of the posterior"),
    Edit("histogram_filter", "histogram_predict(belief, transition)",
         "histogram_predict(belief, transition.T)",
         keyword="transposed", mistake="transposed motion model passed"),
    Edit("histogram_filter", "likelihood = sensor_likelihood(world, z, p_correct)",
         "likelihood = sensor_likelihood(world, measurements[k - 1], p_correct)",
         keyword="off by one", mistake="the previous step's measurement"),
    Edit("histogram_filter", "likelihood = sensor_likelihood(world, z, p_correct)",
         "likelihood = sensor_likelihood(world, z, 1 - p_correct)",
         keyword="swapped", mistake="1 - p_correct passed to the sensor model"),
    Edit("histogram_filter", "likelihood = sensor_likelihood(world, z, p_correct)",
         "likelihood = sensor_likelihood(CORRIDOR, z, p_correct)",
         keyword="world argument", mistake="the global CORRIDOR instead of world"),
    Edit("histogram_filter", "likelihood = sensor_likelihood(world, z, p_correct)",
         "likelihood = sensor_likelihood(world, z, 0.85)",
         keyword="whatever p_correct is", mistake="p_correct hard-coded as the notebook's 0.85"),
    Edit("histogram_filter", "belief = belief0",
         "belief = np.full(len(world), 1.0 / len(world))",
         keyword="belief0 argument", mistake="starts from a uniform belief, belief0 ignored"),
    Edit("histogram_filter", "likelihood = sensor_likelihood(world, z, p_correct)",
         "likelihood = sensor_likelihood(world, measurements[0], p_correct)",
         keyword="every update uses", mistake="the first measurement at every step"),
    Edit("histogram_filter", _LOOP,
         "for z in measurements:\n"
         "        belief = histogram_update(belief, sensor_likelihood(world, z, p_correct))\n"
         "        belief = histogram_predict(belief, transition)\n"
         "        beliefs.append(belief)",
         keyword="after the next prediction", mistake="predicts after the update and stores that"),
    Edit("histogram_filter", _STORE,
         "belief = histogram_update(belief, likelihood)\n"
         "        if k == 0:\n"
         "            out = belief.copy()\n"
         "        out[:] = belief\n"
         "        beliefs.append(out)",
         keyword="in place", mistake="one buffer appended at every step and overwritten"),
    # --- behaviour: arguments changed in place, single precision (issue 25) -----------------
    Edit("histogram_update", "unnormalised = likelihood * belief",
         "belief *= likelihood\n    unnormalised = belief",
         keyword="in place", mistake="the prior multiplied by the likelihood in place"),
    Edit("histogram_update", _UPD,
         "unnormalised /= unnormalised.sum()\n    belief[:] = unnormalised\n    posterior = belief",
         keyword="in place", mistake="the posterior written into the caller's prior"),
    Edit("histogram_predict", _PRED,
         "belief[:] = transition @ belief\n    return belief",
         keyword="in place", mistake="the prediction written into the caller's belief"),
    Edit("door_likelihood", _LIK,
         "return np.where(world == z, p_correct, 1.0 - p_correct).astype(np.float32)",
         keyword="single precision", mistake="the likelihood in float32"),
    Edit("histogram_predict", _PRED, "return (transition @ belief).astype(np.float32)",
         keyword="single precision", mistake="the predicted belief in float32"),
    # a recursion whose histogram_update normalises the caller's prior in place: named by the
    # update's own check (the run itself is right)
    Edit("histogram_filter", "unnormalised = likelihood * belief", "belief *= likelihood\n    unnormalised = belief",
         cell="update", keyword="fix histogram_update first",
         mistake="histogram_update multiplies the prior in place"),
    Edit("histogram_filter", "return np.array(beliefs)", "return belief",
         keyword="every step", mistake="only the last posterior returned"),
    Edit("histogram_filter", "for k, z in enumerate(measurements):",
         "for k, z in enumerate(measurements[1:]):",
         keyword="off by one", mistake="the first measurement skipped"),
    # an upstream function is wrong, the recursion itself is right: blame the upstream one
    Edit("histogram_filter", _PRED, "return transition.T @ belief", cell="predict",
         keyword="fix histogram_predict first", mistake="a transposed histogram_predict"),
    Edit("histogram_filter", _UPD, "posterior = unnormalised", cell="update",
         keyword="fix histogram_update first", mistake="an unnormalised histogram_update"),
    Edit("histogram_filter", _LIK, "return np.where(world == z, 1.0 - p_correct, p_correct)",
         cell="likelihood", keyword="fix sensor_likelihood first", mistake="a swapped sensor_likelihood"),

    # --- the stubs of the exercise (issue 14), and the whole steps' plausible mistakes -----
    Edit("door_likelihood", _LIK,
         "p_door = np.where(world == 1, p_correct, 1.0 - p_correct)   # p(reading \"door\" | x = i)\n"
         "    return p_door",
         keyword="depend on z", mistake="p(reading 'door' | x) whatever was read (the stub)"),
    Edit("door_likelihood", _LIK,
         "p_door = np.where(world == 1, p_correct, 1.0 - p_correct)\n"
         "    return p_door if z == 0 else 1.0 - p_door",
         keyword="swapped", mistake="the stub's p_door, complemented for the wrong reading"),
    Edit("histogram_update", _BAYES, "posterior = belief",
         keyword="measurement was not used", mistake="the posterior is the prior (the stub)"),
    Edit("histogram_update", _BAYES, "posterior = likelihood * belief",
         keyword="evidence", mistake="likelihood × prior, never normalised"),
    Edit("histogram_update", _BAYES, "posterior = likelihood / likelihood.sum()",
         keyword="prior is missing", mistake="the normalised likelihood, prior forgotten"),
    Edit("histogram_update", _BAYES, "posterior = likelihood * belief / likelihood.sum()",
         keyword="evidence", mistake="normalised by the likelihood's sum instead of the evidence"),
    Edit("histogram_update", _BAYES,
         "posterior = (likelihood + belief) / (likelihood + belief).sum()",
         keyword="does not add", mistake="prior and likelihood added, then normalised"),
    Edit("histogram_filter", _STEP, "belief = histogram_update(belief0, likelihood)",
         keyword="restarts from belief0", mistake="each reading on its own, from belief0 (the stub)"),
    Edit("histogram_filter", _STEP,
         "belief = histogram_update(belief, likelihood)\n"
         "        belief = histogram_predict(belief, transition)",
         keyword="after the next prediction", mistake="update, then predict, and the prediction stored"),
    Edit("histogram_filter", _STEP,
         "belief = histogram_predict(belief, transition)\n"
         "        belief = histogram_update(belief, likelihood)",
         keyword="before the first measurement", mistake="a prediction at every step, step 0 included"),
    Edit("histogram_filter", _STEP, "belief = histogram_update(belief, likelihood)",
         keyword="prediction step is missing", mistake="no motion between readings"),
    Edit("histogram_filter", _STEP,
         "if k > 0:\n"
         "            belief = histogram_predict(belief0, transition)\n"
         "        belief = histogram_update(belief, likelihood)",
         keyword="from belief0", mistake="every prediction from belief0"),
    Edit("histogram_filter", _STEP,
         "prior = histogram_predict(belief, transition) if k > 0 else belief\n"
         "        belief = histogram_update(belief, likelihood)",
         keyword="prediction step is missing", mistake="the prediction stored under another name, unused"),

    # --- corridor_motion_model (optional challenge): circular_motion_model(n, step_probs) --
    Edit("corridor_motion_model", _RING, "transition += prob * np.eye(n, k=offset)",
         keyword="lost at the end", mistake="shifted identities: no wrap-around, and backwards (the stub)"),
    Edit("corridor_motion_model", _RING, "transition += prob * np.eye(n, k=-offset)",
         keyword="lost at the end", mistake="shifted identities in the right direction, no wrap-around"),
    Edit("corridor_motion_model", _RING,
         "for j in range(n):\n"
         "            if 0 <= j + offset < n:\n"
         "                transition[j + offset, j] += prob",
         keyword="circular", mistake="a straight corridor: steps past either end dropped"),
    Edit("corridor_motion_model", _RING,
         "for j in range(n):\n            transition[j, (j + offset) % n] += prob",
         keyword="transposed", mistake="[from, to] instead of [to, from]"),
    Edit("corridor_motion_model", _RING,
         "for j in range(n):\n            transition[(j - offset) % n, j] += prob",
         keyword="backwards", mistake="the offset subtracted"),
    Edit("corridor_motion_model", _RING,
         "transition += prob * np.roll(np.eye(n), offset, axis=1)",
         keyword="transposed", mistake="the identity rolled along the wrong axis"),
    Edit("corridor_motion_model", _RING,
         "for j in range(n):\n            transition[(j + offset) % n, j] = prob",
         keyword="add up", mistake="each probability written, not added (offsets equal modulo n)"),
    Edit("corridor_motion_model", "for offset, prob in step_probs.items():",
         "for offset, prob in enumerate(step_probs.values()):",
         keyword="keys of step_probs", mistake="offsets taken as 0, 1, 2, ..."),
    Edit("corridor_motion_model", "transition = np.zeros((n, n))", "transition = np.zeros((20, 20))",
         keyword="shape", mistake="the notebook's 20 cells hard-coded"),
]

EQUIVALENTS = [
    Edit("door_likelihood", _LIK,
         "return [p_correct if w == z else 1.0 - p_correct for w in world]",
         mistake="a list comprehension returning a list"),
    Edit("door_likelihood", _LIK,
         "return (world == z) * p_correct + (world != z) * (1.0 - p_correct)",
         mistake="boolean masks as 0/1 weights"),
    Edit("door_likelihood", _LIK,
         "lik = np.full(world.shape, 1.0 - p_correct)\n    lik[world == z] = p_correct\n    return lik",
         mistake="fill, then assign the agreeing cells"),
    Edit("histogram_update", _UPD, "posterior = unnormalised / np.dot(likelihood, belief)",
         mistake="the evidence as a dot product"),
    Edit("histogram_update", "unnormalised = likelihood * belief",
         "unnormalised = np.exp(np.log(likelihood) + np.log(belief))",
         mistake="the product in the log domain"),
    Edit("histogram_update", _UPD,
         "posterior = np.array([u / sum(unnormalised) for u in unnormalised])",
         mistake="a Python loop"),
    Edit("histogram_predict", _PRED, "return np.einsum('ij,j->i', transition, belief)",
         mistake="einsum"),
    Edit("histogram_predict", _PRED, "return (transition * belief).sum(axis=1)",
         mistake="element-wise product summed over j (axis 1)"),
    Edit("histogram_predict", _PRED, "return belief @ transition.T",
         mistake="row vector times the transpose"),
    Edit("histogram_predict", _PRED,
         "out = np.zeros(len(belief))\n    for i in range(len(belief)):\n"
         "        for j in range(len(belief)):\n            out[i] += transition[i, j] * belief[j]\n"
         "    return out",
         mistake="a double loop"),
    Edit("histogram_predict", _PRED, "return list(transition @ belief)", mistake="a list return"),
    Edit("histogram_filter", _LOOP,
         "for z in measurements:\n"
         "        belief = histogram_update(belief, sensor_likelihood(world, z, p_correct))\n"
         "        beliefs.append(belief)\n"
         "        belief = histogram_predict(belief, transition)",
         mistake="predict at the end of each step (after storing the posterior)"),
    Edit("histogram_filter", "return np.array(beliefs)", "return np.vstack(beliefs)",
         mistake="np.vstack instead of np.array"),
    Edit("histogram_filter", "return np.array(beliefs)", "return [list(b) for b in beliefs]",
         mistake="a list of lists"),
    Edit("door_likelihood", _LIK,
         "p_door = np.where(world == 1, p_correct, 1.0 - p_correct)   # p(reading \"door\" | x = i)\n"
         "    return p_door if z == 1 else 1.0 - p_door",
         mistake="the stub's p_door, complemented for a 'wall' reading"),
    Edit("histogram_update", _BAYES,
         "evidence = likelihood @ belief                  # p(z)\n"
         "    posterior = likelihood * belief / evidence",
         mistake="the evidence first, as a dot product"),
    Edit("histogram_update", _BAYES,
         "log_post = np.log(likelihood) + np.log(belief)\n"
         "    posterior = np.exp(log_post - log_post.max())\n"
         "    posterior = posterior / posterior.sum()",
         mistake="the log domain, shifted by its maximum"),
    Edit("histogram_filter", _STEP,
         "prior = belief if k == 0 else histogram_predict(belief, transition)\n"
         "        belief = histogram_update(prior, likelihood)",
         mistake="the prior named, a conditional expression"),
    Edit("histogram_filter", _STEP,
         "if k:\n"
         "            belief = histogram_predict(belief, transition)\n"
         "        belief = histogram_update(belief, likelihood)",
         mistake="if k: instead of if k > 0:"),
    Edit("corridor_motion_model", _RING,
         "transition += prob * np.roll(np.eye(n), offset, axis=0)",
         mistake="the identity rolled down by the offset"),
    Edit("corridor_motion_model", _RING,
         "np.add.at(transition, ((np.arange(n) + offset) % n, np.arange(n)), prob)",
         mistake="np.add.at with index arrays"),
    Edit("corridor_motion_model", _RING,
         "for i in range(n):\n            transition[i, (i - offset) % n] += prob",
         mistake="a loop over the destination cells"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("histogram_predict", _PRED,
               "out = transition @ belief\n    return out / out.sum()",
               reason="transition @ belief already sums to 1 (columns of transition sum to 1): "
                      "normalising it again changes it by round-off only"),
    Equivalent("histogram_filter", _RUN, "belief = histogram_update(likelihood, belief)",
               reason="the update multiplies its two arguments element-wise, so their order "
                      "cannot change the posterior"),
    Equivalent("histogram_update", _UPD,
               "posterior = unnormalised / unnormalised.sum()\n    posterior = posterior / posterior.sum()",
               reason="normalising an already normalised vector changes it by round-off only"),
]
