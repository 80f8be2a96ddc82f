"""The files of a path's stability: its CSV tables (:func:`table_writers`) and, with its
figures, a whole study's folder (:func:`write_study`)."""

from __future__ import annotations

import csv
from pathlib import Path

from ..io import write_outputs
from .locate import PathStability, _components


def table_writers(ps: PathStability) -> dict:
    """The CSV tables of a path's stability, as writers ``name -> write(path)`` for
    :func:`hmodel.io.write_outputs`: ``path.csv`` (the loading increments' normalized d²W),
    ``probes.csv`` (the probes' minimum per probed state), ``summary.csv`` (bifurcation-domain
    entry and loss of controllability) and, with envelopes, ``envelopes.csv``."""

    comps = _components(ps.result)
    normal = [f"{x}{c}" for x in ("eps", "sig") for c in comps if c[0] == c[1]]

    def write_path(p: Path) -> None:
        sh = ps.result
        sh = type(sh)({k: v[sh["stage"] != "consolidation"] for k, v in sh.columns.items()}, sh.meta)
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["step", "stage", "axial_strain", *normal, "q", "p", "d2W_loading_normalized"])
            for i in range(len(ps.shear_strain)):
                w.writerow([sh["step"][i], sh["stage"][i], ps.shear_strain[i],
                            *(sh[c][i] for c in normal), sh["q"][i], sh["p"][i], ps.loading_w[i]])

    def write_checks(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["step", "axial_strain", "probe_magnitude", "min_d2W_normalized"])
            w.writerows(zip(ps.check_step, ps.check_strain, ps.check_magnitude, ps.check_min_w))

    def write_envelopes(p: Path) -> None:
        with open(p, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["axial_strain", "probe", "kind", *(f"deps{c}" for c in comps),
                        *(f"dsig{c}" for c in comps), "d2W", "d2W_normalized"])
            for strain, envs in sorted(ps.envelopes.items()):
                for env in envs:
                    for k in range(len(env.deps)):
                        w.writerow([strain, k, env.kind, *env.deps[k], *env.dsig[k], env.work[k],
                                    env.normalized[k]])

    def write_summary(p: Path) -> None:
        p.write_text("quantity,axial_strain,step,found_by\n"
                     f"bifurcation_domain_entry,{ps.bifurcation},{ps.bifurcation_step},{ps.bifurcation_by}\n"
                     f"loss_of_controllability,{ps.controllability},{ps.controllability_step},{ps.controllability_by}\n")


    files = {"path.csv": write_path, "probes.csv": write_checks, "summary.csv": write_summary}
    if ps.envelopes:
        files["envelopes.csv"] = write_envelopes
    return files


def write_study(study, out: Path) -> None:
    """Write a :class:`~hmodel.stability.study.StabilityStudy` into the folder ``out``
    (:func:`hmodel.io.write_outputs`): the tables of :func:`table_writers`, ``d2W-path.png``
    and, with envelopes, ``envelopes.png`` (:mod:`hmodel.stability.figures`)."""
    from .figures import plot_envelopes, plot_path

    ps = study.stability
    files = {**table_writers(ps), "d2W-path.png": lambda p: plot_path(ps, p, study.title)}
    if ps.envelopes:
        files["envelopes.png"] = lambda p: plot_envelopes(ps.envelopes, p, study.title)
    write_outputs(out, files)
