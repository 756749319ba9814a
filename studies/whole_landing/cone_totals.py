"""The landing's totals against the friction cone, a check ``random_landings.py`` does not make.

Each FILE lands through the CLI (``footopt evaluate FILE --json``, its output discarded) with a spy
on ``model_choice.landing`` that keeps the LandingResult; per contact the totals' friction ratio
|sum T_k| / (mu sum N_k) (on flat ground a sum of impulses each inside one fixed cone: at most 1
to rounding; on a terrain or heightfield the tangent bases turn, so only roughly), the worst
contact, and the smallest normal total (a negative one pulls). One JSON line per file to OUT.
Found: random file 31088's nearly redundant pair, whose ``arrest`` projections put 590 N s of
tangential squeeze on a contact with 1.8 N s of normal impulse (``spatial_chatter.md``, the
section "Sweeps at 49dd60a").

Run: PYTHONPATH=. python studies/whole_landing/cone_totals.py OUT.jsonl FILE...
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import time

import numpy as np

import optimizer.evaluation.model_choice as choice
from optimizer.cli.main import main


def cone_record(path: str) -> dict:
    """One file's record: exit status, seconds and, where a landing ran, its totals against the cone."""
    spied: dict = {}
    real = choice.landing

    def spy(*args, **kwargs):  # keep the LandingResult and its scene
        spied["result"], spied["scene"] = real(*args, **kwargs), args[1]
        return spied["result"]

    choice.landing = spy
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = main(["evaluate", path, "--json"])
    except BaseException as ex:  # a crash is a record too
        status = f"raised {type(ex).__name__}"
    finally:
        choice.landing = real
    record = {"file": os.path.basename(path), "status": status, "seconds": round(time.perf_counter() - t0, 1)}
    if "result" in spied:
        record.update(_against_the_cone(spied["result"], spied["scene"]))
    return record


def _against_the_cone(result, scene) -> dict:
    """Per contact |sum T| / (mu sum N) (|sum T| without friction), the worst contact and the normal totals."""
    N = np.asarray(result.total_external, float)
    tn = np.linalg.norm(np.asarray(result.total_tangential, float).reshape(len(N), -1), axis=1)
    mu = float(scene.friction)
    flat = scene.terrain.is_flat and (scene.heightfield is None or scene.heightfield.is_flat)
    if mu > 0:
        ratio = np.where(N > 1e-9, tn / np.maximum(mu * N, 1e-300), np.where(tn > 1e-9, np.inf, 0.0))
    else:
        ratio = tn
    k = int(np.argmax(ratio))
    return dict(mu=mu, flat=bool(flat), worst_ratio=float(ratio[k]), contact=k, N=float(N[k]), T=float(tn[k]),
                minN=float(N.min()), sumN=float(N.sum()), maxN=float(N.max()))


if __name__ == "__main__":
    with open(sys.argv[1], "a") as out:
        for f in sys.argv[2:]:
            out.write(json.dumps(cone_record(f)) + "\n")
            out.flush()
