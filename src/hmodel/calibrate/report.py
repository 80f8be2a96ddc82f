"""What a calibration writes: ``calibration.json``, ``fit.csv`` and ``fit.png`` (and, with a
check at the optimum, ``check.csv``)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..io import write_outputs
from .check import Check
from .fitting import Calibration


def write(cal: Calibration, out_dir, check: Check | None = None) -> list[Path]:
    """Write the calibration's files into ``out_dir`` (all or nothing): ``calibration.json``,
    ``fit.csv``, ``fit.png``; for ``bayes``, ``posterior.csv``, ``corner.png`` and
    ``trace.png``; with a ``check`` (:func:`~hmodel.calibrate.check.check_at`), its record in
    ``calibration.json``, its curves in ``fit.png`` (dashed) and ``check.csv``."""
    writers = {"calibration.json": lambda p: _json(cal, p, check), "fit.csv": lambda p: _csv(cal, p),
               "fit.png": lambda p: _figure(cal, p, check)}
    if check is not None and not check.failed:
        writers["check.csv"] = lambda p: _check_csv(cal, check, p)
    if cal.posterior is not None:
        writers |= {"posterior.csv": lambda p: _posterior(cal, p), "corner.png": lambda p: _corner(cal, p),
                    "trace.png": lambda p: _trace(cal, p)}
    return write_outputs(out_dir, writers)


def _posterior(cal: Calibration, path: Path) -> None:
    """The posterior samples after burn-in, CLI units (angles in degrees)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cal.space.names)
        for row in cal.posterior.samples:
            w.writerow([repr(float(x)) for x in row])


def _corner(cal: Calibration, path: Path) -> None:
    import corner  # only when a posterior is drawn

    n = cal.space.n
    fig = Figure(figsize=(2.2 * n + 1, 2.2 * n + 1))
    corner.corner(cal.posterior.samples, labels=list(cal.space.names), quantiles=[0.05, 0.5, 0.95],
                  show_titles=True, title_fmt=".4g", fig=fig)
    fig.savefig(path, dpi=100)


def _trace(cal: Calibration, path: Path) -> None:
    """Every walker against the step, per parameter; the burn-in shaded."""
    chain, n = cal.posterior.chain, cal.space.n
    fig = Figure(figsize=(8, 1.8 * n + 0.6))
    axes = np.atleast_1d(fig.subplots(n, 1, sharex=True))
    for j, ax in enumerate(axes):
        ax.plot(chain[:, :, j], lw=0.5, alpha=0.5, color="k")
        ax.axvspan(0, cal.posterior.burn, color="C1", alpha=0.15)
        ax.set_ylabel(cal.space.names[j])
    axes[-1].set_xlabel("step")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _json(cal: Calibration, path: Path, check: Check | None) -> None:
    rec = cal.to_dict() | ({"check": check.to_dict()} if check is not None else {})
    path.write_text(json.dumps(rec, indent=2) + "\n")


def _check_csv(cal: Calibration, check: Check, path: Path) -> None:
    """The calibrated model's curves beside the check solver's at the test's axial strains."""
    _curves_csv(path, ["q_model", "q_check", "eps_v_model", "eps_v_check"], cal.tests,
                [(q[0], qc, ev[0], evc) for q, ev, qc, evc
                 in zip(cal.prediction.q, cal.prediction.eps_v, check.q, check.eps_v)])


def _csv(cal: Calibration, path: Path) -> None:
    """Every test row beside the calibrated model's values at the same axial strain."""
    _curves_csv(path, ["q", "q_model", "eps_v", "eps_v_model"], cal.tests,
                [(t.q, q[0], t.eps_v if t.eps_v is not None else np.full(len(t.eps11), np.nan), ev[0])
                 for t, q, ev in zip(cal.tests, cal.prediction.q, cal.prediction.eps_v)])


def _curves_csv(path: Path, names: list[str], tests, columns: list[tuple]) -> None:
    """One row per test row: the test's name, kind, p0 and ε11, then that test's ``columns``."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["test", "kind", "p0", "eps11", *names])
        for t, cols in zip(tests, columns):
            for row in zip(t.eps11, *cols):
                w.writerow([t.name, t.kind, repr(t.p0), *(repr(float(x)) for x in row)])


def _figure(cal: Calibration, path: Path, check: Check | None = None) -> None:
    """q and εv against ε11: each test (markers), the calibrated model (lines) and, with a
    check, the check solver at the same parameters (dashed)."""
    fig = Figure(figsize=(10, 4.2))
    ax_q, ax_v = fig.subplots(1, 2)
    for k, (t, q, ev) in enumerate(zip(cal.tests, cal.prediction.q, cal.prediction.eps_v)):
        color = f"C{k % 10}"
        if cal.band is not None:  # the 90 % posterior predictive band
            (q_lo, q_hi), (v_lo, v_hi) = cal.band[k]
            ax_q.fill_between(100 * t.eps11, q_lo / 1e3, q_hi / 1e3, color=color, alpha=0.25, lw=0)
            ax_v.fill_between(100 * t.eps11, 100 * v_lo, 100 * v_hi, color=color, alpha=0.25, lw=0)
        ax_q.plot(100 * t.eps11, t.q / 1e3, "o", ms=3, color=color, label=f"{t.name} (test)")
        ax_q.plot(100 * t.eps11, q[0] / 1e3, "-", color=color, label="model")
        if t.eps_v is not None:
            ax_v.plot(100 * t.eps11, 100 * t.eps_v, "o", ms=3, color=color)
        ax_v.plot(100 * t.eps11, 100 * ev[0], "-", color=color)
        if check is not None and not check.failed:
            ax_q.plot(100 * t.eps11, check.q[k] / 1e3, "--", color=color, lw=1,
                      label=f"{check.solver} (check)" if k == 0 else None)
            ax_v.plot(100 * t.eps11, 100 * check.eps_v[k], "--", color=color, lw=1)
    finish_figure(fig, ax_q, ax_v, f"{cal.method}: {fitted_text(cal)}", path)


def fitted_text(cal: Calibration) -> str:
    """``name = value, ...`` of the fitted parameters, for figure titles."""
    return ", ".join(f"{n} = {v:.4g}" for n, v in cal.fitted.items())


def finish_figure(fig, ax_q, ax_v, title: str, path: Path, legend_size: float = 7) -> None:
    """Title, axis labels, legend and grid of a q / εv against ε11 figure, then save it."""
    fig.suptitle(title, fontsize=9)
    ax_q.set(xlabel="ε11 [%]", ylabel="q [kPa]")
    ax_v.set(xlabel="ε11 [%]", ylabel="εv [%] (compression positive)")
    ax_q.legend(fontsize=legend_size)
    for ax in (ax_q, ax_v):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
