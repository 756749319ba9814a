"""Seeded random trees' answers (planar, planar read as spatial, spatial: Newton; spatial: the
exact cone) as hex floats: rod_answers_871616f.json, written by commit 871616f's code (before
com_offset and inertia_tensor) with

    git archive 871616f | tar -x -C /tmp/old && cp tests/impulse_core/data/make_rod_answers.py /tmp/old/ && cd /tmp/old && PYTHONPATH=. python make_rod_answers.py out.json

tests/impulse_core/test_spatial_inertia.py checks today's code gives them bit for bit."""
import dataclasses, json, sys
import numpy as np
import impulse_core
from impulse_core.evaluate import evaluate
from impulse_core.impact.laws import ImpactModel
from impulse_core.kinematics.spatial import PLANAR, SPATIAL
from tests.conftest import random_tree
from tests.impulse_core.test_spatial import SCENE, spatial_trees
print(impulse_core.__file__, file=sys.stderr)
out = {}
def hexes(a): return [float(x).hex() for x in np.asarray(a, dtype=float).ravel()]
def record(r): return {"external": hexes(r.external), "internal": hexes(r.internal_magnitude), "v_plus": hexes(r.v_plus)}
for k, t in enumerate(spatial_trees()):
    out[f"spatial{k}.newton"] = record(evaluate(t, SCENE, ImpactModel.NEWTON, space=SPATIAL))
    if k < 10:
        out[f"spatial{k}.friction"] = record(evaluate(t, dataclasses.replace(SCENE, friction=0.5), ImpactModel.FRICTION, space=SPATIAL))
rng = np.random.default_rng(7)
scene = dataclasses.replace(SCENE, velocity_z=0.0, angular_velocity_x=0.0, angular_velocity_y=0.0)
for k in range(15):
    t = random_tree(rng, int(rng.integers(1, 8)), p_contact=0.6)
    out[f"planar{k}.newton"] = record(evaluate(t, scene, ImpactModel.NEWTON, space=PLANAR))
    out[f"planar{k}.as_spatial"] = record(evaluate(t, scene, ImpactModel.NEWTON, space=SPATIAL))
json.dump(out, open(sys.argv[1], "w"), indent=0)
