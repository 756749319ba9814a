"""``python studies/whole_landing/stiff_joint.py FILE [HEEL_STIFFNESS|-] [STEP_CODE]``: one landing of FILE
(``landing()``'s defaults; the heel, ``model.bodies[2]``, given that stiffness) and its CPU time, with a
digest of its trajectory, impulses and final angles to compare two trees' landings to the bit
(``stiff_joint.md``: run it with PYTHONPATH on each tree)."""

import hashlib
import sys
import time
from dataclasses import replace

import numpy as np

from impulse_core.timedomain.landing import LandingSettings, landing
from optimizer.config.model_file import load_model_file

model = load_model_file(sys.argv[1])
joints = model.joints
if len(sys.argv) > 2 and sys.argv[2] != "-":
    joints = tuple(replace(j, stiffness=float(sys.argv[2])) if i == 2 else j for i, j in enumerate(joints))
code = sys.argv[3] if len(sys.argv) > 3 else "auto"
start = time.process_time()
try:
    r = landing(model.tree, model.scene, joints, LandingSettings(step_code=code), model.space)
except Exception as e:  # noqa: BLE001 - reported, with its CPU time
    print("ERR", type(e).__name__, str(e)[:150], "cpu", round(time.process_time() - start, 2))
    sys.exit()
cpu = time.process_time() - start
parts = [r.trajectory[0], r.trajectory[1], np.array([r.peak_external_norm, r.peak_internal_norm, r.error_estimate,
                                                     r.momentum_balance, r.step, r.n_steps]),
         np.asarray(r.final_angles), np.asarray(r.total_external)]
digest = hashlib.sha256(b"".join(np.ascontiguousarray(p, dtype=float).tobytes() for p in parts)).hexdigest()[:16]
print("digest", digest, "int", r.integrator, "steps", r.n_steps, "err %.3g" % r.error_estimate,
      "peak %.10g" % r.peak_external_norm, "bal %.2g" % r.momentum_balance, "switch", r.integrator_switch[:60],
      "cpu", round(cpu, 2))
