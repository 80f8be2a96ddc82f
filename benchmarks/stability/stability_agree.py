"""Entry into the bifurcation domain against the loss of controllability, by probe settings.

Biaxial tests from p0 = 200 kPa to 2 % axial strain (drained, lateral stress held; undrained,
isochoric), loose and dense (alpha0 = 60° and 45°), nθ = 360, 72 strain probes, axial
increment 1e-4. Settings:

- ``before``: the settings before issue 24 (probes of 1e-5 at every 10th state; the loading
  increments not counted);
- ``probes 1e-5, every state``; ``probes tied, every state``: probes of 1e-5, or of the norm
  of the loading increment (1.4e-4 undrained), at every state, the loading increments not counted;
- ``default``: probes tied to the increment at every 10th state and every state from the
  approach of the domain until the probes find it, the loading increments counted as probes.

Usage: ``python -m benchmarks.stability.stability_agree``; writes ``stability_agree.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from benchmarks.timing import record
from hmodel import Params
from hmodel.stability import along_biaxial

SETTINGS = {"before": dict(magnitude=1e-5, every=10, loading_probe=False, near=-2.0),
            "probes 1e-5, every state": dict(magnitude=1e-5, every=1, loading_probe=False),
            "probes tied, every state": dict(every=1, loading_probe=False),
            "default": dict()}


def pct(v: float) -> float | None:
    return None if not math.isfinite(v) else round(100 * v, 4)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-theta", type=int, default=360)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("stability_agree.json"))
    args = ap.parse_args()
    rows = []
    for material, alpha0 in (("loose", 60.0), ("dense", 45.0)):
        for undrained in (True, False):
            P = Params(alpha0=math.radians(alpha0), n_theta=args.n_theta)
            for name, kw in SETTINGS.items():
                ps = along_biaxial(P, 2e5, 0.02, undrained=undrained, **kw)
                rows.append({"material": material, "path": "undrained" if undrained else "drained",
                             "settings": name, "entry_pct": pct(ps.bifurcation),
                             "found_by": ps.bifurcation_by or None,
                             "controllability_lost_pct": pct(ps.controllability),
                             "probed_states": len(ps.check_step)})
                print(rows[-1], flush=True)
    rec = record(__file__, args, 1, [], n_theta=args.n_theta, p0_kPa=200, axial_strain=0.02, paths=rows)
    rec.pop("results")
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
