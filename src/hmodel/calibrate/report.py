"""What a calibration writes: ``calibration.json``, ``fit.csv`` and ``fit.png``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..io import write_outputs
from .fitting import Calibration


def write(cal: Calibration, out_dir) -> list[Path]:
    """Write the calibration's files into ``out_dir`` (all or nothing)."""
    return write_outputs(out_dir, {"calibration.json": lambda p: _json(cal, p),
                                   "fit.csv": lambda p: _csv(cal, p),
                                   "fit.png": lambda p: _figure(cal, p)})


def _json(cal: Calibration, path: Path) -> None:
    path.write_text(json.dumps(cal.to_dict(), indent=2) + "\n")


def _csv(cal: Calibration, path: Path) -> None:
    """Every test row beside the calibrated model's values at the same axial strain."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["test", "kind", "p0", "eps11", "q", "q_model", "eps_v", "eps_v_model"])
        for t, q, ev in zip(cal.tests, cal.prediction.q, cal.prediction.eps_v):
            data_ev = t.eps_v if t.eps_v is not None else np.full(len(t.eps11), np.nan)
            for row in zip(t.eps11, t.q, q[0], data_ev, ev[0]):
                w.writerow([t.name, t.kind, repr(t.p0), *(repr(float(x)) for x in row)])


def _figure(cal: Calibration, path: Path) -> None:
    """q and εv against ε11: each test (markers) and the calibrated model (lines)."""
    fig = Figure(figsize=(10, 4.2))
    ax_q, ax_v = fig.subplots(1, 2)
    for k, (t, q, ev) in enumerate(zip(cal.tests, cal.prediction.q, cal.prediction.eps_v)):
        color = f"C{k % 10}"
        ax_q.plot(100 * t.eps11, t.q / 1e3, "o", ms=3, color=color, label=f"{t.name} (test)")
        ax_q.plot(100 * t.eps11, q[0] / 1e3, "-", color=color, label="model")
        if t.eps_v is not None:
            ax_v.plot(100 * t.eps11, 100 * t.eps_v, "o", ms=3, color=color)
        ax_v.plot(100 * t.eps11, 100 * ev[0], "-", color=color)
    fitted = ", ".join(f"{n} = {v:.4g}" for n, v in cal.fitted.items())
    ax_q.set(xlabel="ε11 [%]", ylabel="q [kPa]", title=f"{cal.method}: {fitted}")
    ax_v.set(xlabel="ε11 [%]", ylabel="εv [%] (compression positive)")
    ax_q.legend(fontsize=7)
    for ax in (ax_q, ax_v):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
