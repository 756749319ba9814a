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
import sys, io, json, time, contextlib, glob, os
import numpy as np
import optimizer.evaluation.model_choice as choice
from optimizer.cli.main import main
real = choice.landing
spied = {}
def spy(*a, **k):
    r = real(*a, **k); spied["r"] = r; spied["scene"] = a[1]; return r
choice.landing = spy
out_path = sys.argv[1]
files = sys.argv[2:]
with open(out_path, "a") as out:
    for f in files:
        spied.clear()
        t0 = time.perf_counter()
        o, e = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
            try:
                st = main(["evaluate", f, "--json"])
            except BaseException as ex:
                st = f"raised {type(ex).__name__}"
        rec = {"file": os.path.basename(f), "status": st, "seconds": round(time.perf_counter() - t0, 1)}
        if "r" in spied:
            r, sc = spied["r"], spied["scene"]
            N = np.asarray(r.total_external, float)
            T = np.asarray(r.total_tangential, float).reshape(len(N), -1)
            mu = float(sc.friction)
            flat = sc.terrain.is_flat and (sc.heightfield is None or sc.heightfield.is_flat)
            tn = np.linalg.norm(T, axis=1)
            ratio = np.where(N > 1e-9, tn / np.maximum(mu * N, 1e-300), np.where(tn > 1e-9, np.inf, 0.0)) if mu > 0 else tn
            k = int(np.argmax(ratio))
            rec.update(mu=mu, flat=bool(flat), worst_ratio=float(ratio[k]), contact=k, N=float(N[k]), T=float(tn[k]),
                       minN=float(N.min()), sumN=float(N.sum()), maxN=float(N.max()))
        out.write(json.dumps(rec) + "\n"); out.flush()
