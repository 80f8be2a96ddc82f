"""Tests of a DEM sample run in YADE (task ``biaxial`` of :mod:`hmodel.dem.yade` for disks,
``triaxial`` for spheres), one at a time or into a folder that a later run resumes.

:func:`run_test` builds the sample, consolidates it to p0, shears it and returns a
:class:`~hmodel.dem.sample.result.SampleTest`. :func:`run_sample` runs a test per pressure into
one folder (see :mod:`hmodel.dem.sample` for its files); a test whose CSV is there is not run
again, and a folder of another sample is refused.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from types import MappingProxyType
from typing import Callable

import numpy as np

from ...errors import InputError
from ...io import check_output_folder, write_outputs, write_rows
from ...rev.contacts import fabric_rows
from ..yade import DEMError, run
from .packing import initial_packing, mean_diameter
from .result import SampleTest, file_stem, read_table
from .settings import SampleSettings, inertial_number, option_name, strain_rate
from .state import SampleState

#: Settings that may differ between the runs that fill one folder.
RESUME_FREE = ("timeout",)
#: Settings added after folders had been written, with the value every such folder had: a
#: sample.json without them is compared as if it held these.
ADDED_SETTINGS = MappingProxyType({"dim": 2, "contact": "linear", "shear_modulus": None, "poisson": None})


def _check_kind(settings: SampleSettings, kind: str) -> None:
    g = settings.grains
    if kind not in g.kinds:
        raise InputError(f"a {g.sample} runs {', '.join(g.kinds)} tests, not {kind!r}")


def run_test(settings: SampleSettings, kind: str, p0: float) -> SampleTest:
    """Build the sample, consolidate it to p0 and run one test in YADE (biaxial for disks,
    triaxial for spheres).

    Raises
    ------
    InputError
        Bad kind or p0; a target porosity out of reach.
    DEMError
        YADE missing, crashed or timed out; EquilibriumError when the consolidation does not
        reach p0 in equilibrium within ``max_steps``.
    """
    _check_kind(settings, kind)
    if not (isinstance(p0, (int, float)) and math.isfinite(p0) and p0 > 0):
        raise InputError(f"p0 must be a positive pressure, got {p0}")
    settings.check_size()
    r, pos, cell = initial_packing(settings)
    d_mean = mean_diameter(r)
    rate = strain_rate(settings, p0, d_mean)
    spec = {
        "radii": r.tolist(), "pos": pos.tolist(), "cell": list(cell),
        "kn": settings.kn, "kt_kn": settings.kt_kn, "phi_g": math.radians(settings.phi_g),
        "phi_compact": math.radians(settings.friction_compact), "porosity": settings.porosity,
        "density": settings.density, "damping": settings.damping, "dt_safety": settings.dt_safety,
        "p0": p0, "kind": "undrained" if kind.endswith("undrained") else "drained",
        "extension": kind == "triaxial-extension", "strain_rate": rate, "axial_strain": settings.axial_strain,
        "rows": settings.rows,
        "rate_compact": settings.compaction_inertial_number / (d_mean * math.sqrt(settings.density / p0)),
        "period": settings.period, "check": settings.check, "gain": settings.gain,
        "gain_i": settings.gain_i, "lateral_rate_factor": settings.lateral_rate_factor,
        "tol_stress": settings.tol_stress, "tol_unbalanced": settings.tol_unbalanced,
        "max_steps": settings.max_steps,
    }
    if settings.contact != "linear":  # the linear law's request stays as it was
        spec.update(contact=settings.contact, young=settings.young, poisson=settings.poisson)
    t0 = time.perf_counter()
    try:
        out = run(settings.grains.task, spec, timeout=settings.timeout)
    except DEMError as e:
        if "target porosity" in str(e):
            raise InputError(str(e).removeprefix("DEM: ")) from None
        raise
    wall = time.perf_counter() - t0
    rows = np.asarray(out["rows"], float).reshape(-1, len(settings.grains.row_columns))
    test = SampleTest(kind=kind, p0=float(p0), rows=rows,
                      consolidated=SampleState.from_json(out["consolidated"]),
                      final=SampleState.from_json(out["final"]), info={})
    p_min = float(np.min(test.table()["p"]))
    info = {"strain_rate": rate, "mean_diameter": d_mean,
            "inertial_number": inertial_number(rate, d_mean, settings.density, p0),
            "inertial_number_max": inertial_number(rate, d_mean, settings.density, p_min),
            "dt": out["dt"], "consolidation_steps": out["consolidation"]["steps"],
            "consolidation_friction_deg": out["consolidation"]["friction_deg"],
            "shear_steps": out["shear"]["steps"],
            "wall_s": wall, "consolidation_wall_s": out["consolidation"]["wall_s"],
            "shear_wall_s": out["shear"]["wall_s"],
            # YADE's own CPU time: the wall time of a machine shared with other work overstates it
            "yade_cpu_s": out["consolidation"]["cpu_s"] + out["shear"]["cpu_s"],
            "yade_version": out["yade_version"]}
    test.info.update(info)
    return test


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _open_folder(out: Path, settings: SampleSettings, names: list[str]) -> dict:
    """The sample.json of ``out`` to add the tests ``names`` to, or a new one; a folder of another
    sample, or with test CSVs that no sample.json describes, is refused."""
    check_output_folder(out)
    wanted = settings.to_dict()
    meta = _read_json(out / "sample.json")
    if meta is not None:
        old = {**ADDED_SETTINGS, **meta.get("settings", {})}
        diff = sorted(k for k in set(old) | set(wanted)
                      if k not in RESUME_FREE and old.get(k) != wanted.get(k))
        if diff:
            raise InputError(f"{out} holds a sample with other settings "
                             f"({', '.join(option_name(k) for k in diff)}): use another --out")
    elif out.is_dir() and any((out / f"{n}.csv").exists() for n in names):
        raise InputError(f"{out} has test CSVs but no readable sample.json: use another --out")
    meta = meta or {"settings": wanted, "yade_version": None, "tests": {}}
    meta["settings"] = wanted
    return meta


def run_sample(settings: SampleSettings, pressures: list[float], kind: str,
               out: "str | os.PathLike",
               progress: Callable[[str], None] | None = None) -> dict:
    """Run a test of ``kind`` at every pressure into ``out`` (files: :mod:`hmodel.dem.sample`); a test
    whose CSV is already in ``out`` is skipped. Returns the contents of sample.json.

    A folder written with other settings is refused (InputError), so that every test of a
    sample.json shares one sample; each test's files appear together, once it has succeeded.
    """
    _check_kind(settings, kind)
    if not pressures:
        raise InputError("no pressure given")
    for p0 in pressures:
        if not (math.isfinite(p0) and p0 > 0):
            raise InputError(f"p0 must be a positive pressure, got {p0}")
    names = [file_stem(kind, p0) for p0 in pressures]
    if len(set(names)) != len(names):
        raise InputError("the pressures must differ (to 1 Pa): " + ", ".join(names))
    settings.check_size()
    out = Path(out)
    meta = _open_folder(out, settings, names)
    for p0, name in zip(pressures, names):
        if (out / f"{name}.csv").exists():
            if name not in meta["tests"]:
                raise InputError(f"{out / (name + '.csv')} is not described by "
                                 f"{out / 'sample.json'}: remove it or use another --out")
            if progress:
                progress(f"{name}: {name}.csv exists, skipped")
            continue
        test = run_test(settings, kind, p0)
        rec = test.summary()
        rec["axial_strain"] = settings.axial_strain
        meta["tests"][name] = rec
        meta["yade_version"] = test.info["yade_version"]
        meta["tests"] = dict(sorted(meta["tests"].items(), key=lambda kv: (kv[1]["kind"], kv[1]["p0"])))

        def draw(path: Path, meta=meta, test=test, name=name) -> None:
            # this test's files are not in the folder yet
            settings.grains.draw_sample(
                meta["tests"], lambda n: test.final if n == name else SampleState.from_npz(out / f"{n}.npz"),
                lambda n: test.table() if n == name else read_table(out / f"{n}.csv"), path)

        # the CSV last: a test whose CSV exists has all its files
        fabrics = [({"state": state}, f) for state, f in (("consolidated", rec["consolidated"]["fabric"]),
                                                           ("final", rec["final"]["fabric"])) if f is not None]
        write_outputs(out, {f"{name}.npz": test.write_npz,
                            f"{name}_contact_fabric.csv": lambda p, rows=fabric_rows(fabrics): write_rows(rows, p),
                            "sample.json": lambda p, meta=meta: p.write_text(json.dumps(meta, indent=1)),
                            "sample.png": draw,
                            f"{name}.csv": test.write_csv})
        if progress:
            progress(f"{name}: {len(test.rows)} rows, peak q {rec['peak_q'] / 1e3:.4g} kPa, "
                     f"porosity {rec['consolidated']['porosity']:.4f}, z "
                     f"{rec['consolidated']['coordination']:.3f}, I {rec['inertial_number']:.2g}, "
                     f"YADE {rec['wall_s']:.1f} s")
    return meta
