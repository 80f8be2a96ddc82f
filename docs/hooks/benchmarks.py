"""MkDocs hook: the benchmarks page's tables, generated at build time from ``benchmarks/*/*.json``.

The scripts of ``benchmarks/`` are grouped by the documentation page they feed
(``benchmarks/engine/``, ``benchmarks/dem/``, ...) and each writes its JSON file beside itself.
The page (``docs/benchmarks.md``) holds the prose; a marker ``<!-- benchmark: GROUP/NAME -->``
is replaced by the tables of ``benchmarks/GROUP/NAME.json`` and ``<!-- benchmark: * -->`` by
those of every JSON file not placed yet, so a new benchmark shows up without editing the page.
Each file gets a provenance line (date, machine, command) and tables: a dedicated layout for the
main benchmarks, and a generic one (scalars as a settings table, lists of records as tables) for
anything else. Nothing is computed but one verdict: where a measure's target is a number
(``<= 2``, ``0``, ``>= 1e7``), its table says whether the value meets it (:func:`verdict`), and
``<!-- benchmark-targets -->`` is replaced by the count of met and missed targets and a table of
the missed ones, so that a missed target cannot read as a met one.

Everything about where a result comes from is the JSON's own (``benchmarks/timing.py``:
``provenance``): its ``date`` (otherwise the date of the last commit that changed the file), its
``command``, the ``options`` it ran with and its ``input_files``. A file that says
``"command": null`` was written before the scripts recorded their command line, and is shown as
such (with its ``command_note``, where one was noted by hand after the run); a file without a
``command`` at all is an error of the build.
"""

from __future__ import annotations

import json
import logging
import math
import re
import subprocess
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.benchmarks")

PAGE = "benchmarks.md"
MARKER = re.compile(r"<!--\s*benchmark:\s*([\w.*/-]+)\s*-->")
#: Replaced by the count of met and missed targets over every file, and the missed ones.
TARGETS = "<!-- benchmark-targets -->"

#: Fields of :func:`provenance` (``benchmarks/timing.py``), shown in the provenance line and its
#: note rather than as settings.
PROVENANCE = ("date", "command", "command_note", "options", "input_files", "commit", "hmodel",
              "python", "machine", "processor", "cpus")


# --------------------------------------------------------------------------- formatting

_SUPER = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _missing(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x)) or x == [] or x == {} or x == ""


def num(x, sig: int = 4) -> str:
    """A number for a table: thousands separators, ``a·10ⁿ`` for very large or small ones."""
    if _missing(x):
        return "—"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}"
    if isinstance(x, float):
        a = abs(x)
        if a == 0:
            return "0"
        if a >= 1e6 or a < 1e-3:
            m, e = f"{x:.{max(sig - 1, 0)}e}".split("e")
            m = m.rstrip("0").rstrip(".") if "." in m else m
            return f"{'' if m == '1' else m + '·'}10{str(int(e)).translate(_SUPER)}"
        if a >= 1000:
            return f"{x:,.0f}"
        if 0.99 < a < 1.0:  # an R² or a share near 1: two significant digits of what it misses
            return f"{x:.{min(int(math.ceil(-math.log10(1.0 - a))) + 1, 12)}f}"
        return f"{x:.{sig}g}"
    return text(x)


def fixed(digits: int):
    """Formatter with a fixed number of decimals (percentages, seconds)."""
    def fmt(x):
        return "—" if _missing(x) else f"{x + 0.0 if round(x, digits) else 0.0:,.{digits}f}"
    return fmt


def scaled(factor: float, digits: int):
    """Formatter of ``x * factor`` with fixed decimals (s to ms, ...)."""
    return lambda x: fixed(digits)(None if _missing(x) else x * factor)


def text(x) -> str:
    """Any JSON value as one table cell."""
    if _missing(x):
        return "—"
    if isinstance(x, (int, float)) and not isinstance(x, bool):
        return num(x)
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, dict):
        return ", ".join(f"{k}: {text(v)}" for k, v in x.items()) or "—"
    if isinstance(x, list):
        return ", ".join(text(v) for v in x) or "—"
    return str(x).replace("|", "\\|").replace("\n", " ")


def table(rows: list[dict], columns: list[tuple]) -> str:
    """A Markdown table of ``rows``; ``columns`` are (key or callable, header[, formatter]).
    Columns without any value are left out."""
    cols = []
    for spec in columns:
        key, header, fmt = (*spec, None) if len(spec) == 2 else spec
        get = key if callable(key) else (lambda r, k=key: r.get(k))
        values = [get(r) for r in rows]
        if all(_missing(v) for v in values):
            continue
        cols.append((header, [(fmt or text)(v) for v in values]))
    if not cols:
        return ""
    lines = ["| " + " | ".join(h for h, _ in cols) + " |", "|" + "---|" * len(cols)]
    for i in range(len(rows)):
        lines.append("| " + " | ".join(c[i] for _, c in cols) + " |")
    return "\n".join(lines) + "\n"


def settings(d: dict) -> str:
    """Scalars and small dicts of a JSON object as a two-column table."""
    rows = [{"k": k, "v": v} for k, v in d.items()
            if not (isinstance(v, list) and v and isinstance(v[0], dict))]
    return table(rows, [("k", "setting", lambda k: f"`{k}`"), ("v", "value")]) if rows else ""


def generic_tables(d: dict, skip=()) -> str:
    """Every list of records of ``d`` as a table (keys in order of appearance)."""
    out = []
    for key, value in d.items():
        if key in skip or not (isinstance(value, list) and value and isinstance(value[0], dict)):
            continue
        keys = list(dict.fromkeys(k for r in value for k in r))
        out.append(f"**{key}**\n\n" + table(value, [(k, f"`{k}`") for k in keys]))
    return "\n".join(out)


# --------------------------------------------------------------------------- provenance

def _git_date(path: Path) -> str | None:
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cs", "--", path.name], cwd=path.parent,
                             capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def _machine(d: dict) -> str | None:
    parts = []
    m = d.get("machine")
    if isinstance(m, dict):
        parts.append(str(m.get("platform") or m.get("machine") or ""))
        if m.get("cpus"):
            parts.append(f"{m['cpus']} CPUs")
    elif m:
        parts.append(str(m))
    if d.get("processor"):
        parts.append(str(d["processor"]))
    if d.get("cpus") and not (isinstance(m, dict) and m.get("cpus")):
        parts.append(f"{d['cpus']} CPUs")
    if d.get("threads"):
        parts.append(f"{d['threads']} thread(s) per process")
    if d.get("python"):
        parts.append(f"Python {d['python']}")
    if d.get("hmodel"):
        parts.append(f"hmodel {d['hmodel']}")
    parts = [p for p in parts if p]
    return ", ".join(parts) or None


def _script(name: str, scripts: set[str]) -> str | None:
    """The script that writes ``GROUP/NAME.json``: the longest ``GROUP/PREFIX`` of a script
    (``dem/dem_ann_seed1`` is written by ``dem/dem_ann.py``)."""
    stem = name
    while stem and "/" in stem:
        if stem in scripts:
            return f"benchmarks/{stem}.py"
        stem = stem.rpartition("_")[0]
    return None


def _command(name: str, d: dict, scripts: set[str]) -> str:
    """The command line of a record, or what the record says about its absence."""
    if "command" not in d:
        log.warning("benchmarks page: benchmarks/%s.json records no command (benchmarks/timing.py: "
                    "provenance)", name)
        return "*no command in the file*"
    if d["command"]:
        return f"command: `{d['command']}`"
    script = _script(name, scripts)
    note = f"; {d['command_note']}" if d.get("command_note") else ""
    return "command not recorded" + (f" (written by `{script}`{note})" if script else note)


def _inputs(d: dict) -> str:
    """The options and input files of a record as a collapsed note; empty when it has none."""
    rows = [{"k": f"`{k}`", "v": v} for k, v in (d.get("options") or {}).items()]
    rows += [{"k": f"`{f}`", "v": f"SHA-256 {h[:16]}…"} for f, h in (d.get("input_files") or {}).items()]
    if d.get("commit"):
        rows.append({"k": "commit", "v": d["commit"]})
    if not rows:
        return ""
    return "\n??? note \"Options (defaults included) and inputs\"\n\n" + _indent(
        table(rows, [("k", "option or file"), ("v", "value")]))


def provenance(name: str, path: Path, d: dict, scripts: set[str]) -> str:
    date = d.get("date") or d.get("timestamp") or _git_date(path)
    items = [f"`benchmarks/{name}.json`",
             f"recorded {date}" if date else "date not recorded",
             f"machine: {_machine(d)}" if _machine(d) else "machine not recorded"]
    return " · ".join(items) + "  \n" + _command(name, d, scripts) + "\n" + _inputs(d)


# --------------------------------------------------------------------------- layouts

#: Fields of a measure/value/target file that say under which conditions it ran (ann_load.json).
CONDITIONS = ("load_condition", "load_average_before", "numba_threads", "numba_threading_layer",
              "blas", "threads_in_forward")


#: A target that a value can be checked against: a comparison (none: equal) and a number, in
#: the measure's own unit (``<= 2``, ``<= 10 %``, ``>= 1e7``, ``< 594,000``, ``0``). Any other
#: target (``-``, ``small``, ``the noise floor``, ``report 0.998``, ``<= target``) is prose,
#: read by the reader, and gets no verdict.
_TARGET = re.compile(r"^\s*(<=|>=|<|>|=|≤|≥)?\s*([-+]?\d[\d,]*(?:\.\d+)?(?:e[-+]?\d+)?)\s*%?\s*$",
                     re.IGNORECASE)

_COMPARE = {"<=": float.__le__, "≤": float.__le__, ">=": float.__ge__, "≥": float.__ge__,
            "<": float.__lt__, ">": float.__gt__, "=": float.__eq__}


def verdict(value, target) -> str | None:
    """``"met"`` or ``"missed"`` for a measured ``value`` against a numeric ``target``; None
    where the target is not a number to compare with. A missing value (None, NaN: the
    measure was not reached or failed) misses its target.

    >>> verdict(2.4, "<= 2"), verdict(6, "0"), verdict(0.09, "<= 10 %"), verdict(2.7e7, ">= 1e7")
    ('missed', 'missed', 'met', 'met')
    >>> verdict(float("nan"), "< 594,000"), verdict(1.2, "-"), verdict(0.5, "<= target")
    ('missed', None, None)
    """
    m = _TARGET.match(target) if isinstance(target, str) else None
    if m is None:
        return None
    if _missing(value) or isinstance(value, bool) or not isinstance(value, (int, float)):
        return "missed"
    bound = float(m.group(2).replace(",", ""))
    return "met" if _COMPARE[m.group(1) or "="](float(value), bound) else "missed"


def _verdict_cell(v: str | None) -> str | None:
    return {"met": "✓ met", "missed": "✗ **missed**"}.get(v)


def _value(r: dict) -> str:
    v, m = r.get("value"), str(r.get("measure", ""))
    return f"{v:.3g} s" if isinstance(v, float) and not math.isnan(v) and "[s]" in m else num(v, 3)


def _results(d):  # engine.json, stability.json, ann_load.json
    out = table(d["results"], [("measure", "measure"), (_value, "value"), ("target", "target"),
                               (lambda r: _verdict_cell(verdict(r.get("value"), r.get("target"))),
                                "target met?")])
    conditions = {k: d[k] for k in CONDITIONS if k in d}
    out += "\nConditions:\n\n" + settings(conditions) if conditions else ""
    if isinstance(d.get("sets"), list):  # the parameter sets of a family network's files, and per path
        out += "\n" + generic_tables(d, skip=("results",))
    return out


def _data(d):
    out = table(d["generation"], [
        ("dataset", "dataset"), ("workers", "workers"), ("rows", "rows"),
        ("seconds", "time [s]", fixed(1)), ("rows_per_s", "rows/s"),
        ("parent_rss_mb", "peak memory, parent [MB]", fixed(0)),
        (lambda r: r.get("workers_rss_mb") or None, "peak memory, each worker [MB]", fixed(0)),
        ("disk_mb", "on disk [MB]", fixed(0))])
    if d.get("sampling_seconds"):
        out += "\nDrawing 60 k + 10 k rows from Dataset 2:\n\n" + table(
            [{"method": k, "s": v} for k, v in d["sampling_seconds"].items()],
            [("method", "sampling method"), ("s", "time [s]", fixed(1))])
    if d.get("target"):
        out += f"\nTarget: {d['target']}.\n"
    return out


def _surrogate(d):
    def metric(r, output, quantity, key):
        for m in r.get("metrics", []):
            if m.get("output") == output and m.get("quantity") == quantity:
                return m.get(key)
        return None

    def arch(r):
        c = r.get("config", {})
        return f"{c.get('formulation')}, {c.get('depth')}×{c.get('width')} {c.get('activation')}, " \
               f"{c.get('normalization')}"
    cols = [("model", "model"), (arch, "formulation, layers, normalization"),
            ("train_rows", "training rows"), ("seconds", "training [s]", fixed(0)), ("epochs", "epochs")]
    for out, head in (("alpha_next", "R² α′"), ("N1_next", "R² N1′"), ("N2_next", "R² N2′"),
                      ("T1_next", "R² T1′")):
        cols.append((lambda r, o=out: metric(r, o, "state after", "r2"), head, lambda x: f"{x:.7f}"))
    cols.append((lambda r: metric(r, "dN1", "increment", "r2"), "R² ΔN1", lambda x: f"{x:.4f}"))
    cols.append((lambda r: metric(r, "alpha_next", "state after", "max_abs"), "max abs α′ error [rad]",
                 fixed(3)))
    out = table(d["results"], cols)
    for r in d["results"]:
        out += (f"\n??? note \"All metrics: {r.get('model')}\"\n\n"
                + _indent(table(r.get("metrics", []), [
                    ("data", "data"), ("quantity", "quantity"), ("output", "output"), ("mae", "MAE"),
                    ("rmse", "RMSE"), ("r2", "R²", lambda x: f"{x:.7f}"), ("max_abs", "max abs")])))
    return out


def _ann_rev(d):
    return (f"nθ = {d.get('n_theta')}.\n\n" if d.get("n_theta") else "") + table(d["rows"], [
        ("path", "path"), ("in_report", "in the report"), ("step", "step"), ("p0_kPa", "p0 [kPa]"),
        ("q_max_dev_pct_of_peak", "max \\|Δq\\| / peak q [%]", fixed(3)),
        ("q_rms_dev_pct_of_peak", "RMS Δq / peak q [%]", fixed(3)),
        ("eps_v_max_dev_pct_strain", "max \\|Δεv\\| [% strain]", fixed(4)),
        ("seconds_closed_form", "closed form [s]", fixed(3)), ("seconds_surrogate", "ANN [s]", fixed(3)),
        ("surrogate_over_closed_form", "ANN / closed form", fixed(1)),
        ("outside_cells", "cells outside the training domain")])


def _dem_ann(d):
    setup = {k: d[k] for k in ("mesostructure", "solver", "axial_strains", "step", "iso_step",
                               "yade_startup_s") if k in d}
    if d.get("training"):
        setup["training"] = d["training"]
    if d.get("student"):
        s = d["student"]
        setup["student"] = {k: s.get(k) for k in ("epochs", "distill_s", "best_val_loss")}
        setup["student config"] = s.get("config")
    if d.get("datasets"):
        setup["datasets"] = "; ".join(f"Dataset {x.get('kind')}, {x.get('n_directions')} directions over "
                                      f"{x.get('theta_min')}…{x.get('theta_max')}°" for x in d["datasets"])
    out = settings(setup) + "\n"
    out += table(d["rows"], [
        ("path", "path"), ("n_theta", "nθ"), ("axial_pct", "to axial [%]"), ("p0_kPa", "p0 [kPa]"),
        ("status", "status"), ("dem_peak_q_kPa", "DEM peak q [kPa]", fixed(1)),
        ("ann_q_max_dev_pct_of_peak", "ANN max \\|Δq\\| / peak q [%]", fixed(2)),
        ("ann_q_rms_dev_pct_of_peak", "ANN RMS [%]", fixed(2)),
        ("others_q_max_dev_pct_of_peak", "others, max \\|Δq\\| / peak q [%]",
         lambda x: ", ".join(f"{k}: {v:.2f}" for k, v in x.items()) if isinstance(x, dict) else text(x)),
        ("members_q_max_dev_pct_of_peak", "members [%]",
         lambda x: " / ".join(f"{v:.2f}" for v in x) if isinstance(x, list) else text(x)),
        ("closed_form_q_max_dev_pct_of_peak", "closed form [%]", fixed(2)),
        ("ann_failed_at_axial_pct", "ANN failed at axial [%]", fixed(2)),
        ("seconds_dem", "DEM-REV [s]", fixed(2)), ("seconds_ann", "ANN-REV [s]", fixed(4)),
        ("dem_over_ann", "DEM / ANN", fixed(0)), ("dem_requests_per_run", "YADE requests"),
        ("ann_outside_cells", "cells outside")])
    return out


def _dem_ann_speed(d):
    setup = {k: d[k] for k in ("model", "teacher", "members", "solver", "threads") if k in d}
    out = settings(setup) + "\n"
    if d.get("cell"):
        out += "One cell step (network and way back) against a DEM request:\n\n" + table(d["cell"], [
            ("cells", "cells"), ("us_per_cell_dem", "DEM [µs/cell]", fixed(0)),
            ("us_per_cell_ann", "ANN [µs/cell]", fixed(2)), ("us_per_cell_teacher", "teacher [µs/cell]", fixed(2)),
            ("dem_over_ann", "DEM / ANN", fixed(0)), ("dem_over_teacher", "DEM / teacher", fixed(0))]) + "\n"
    if d.get("rev"):
        out += "Drained REVs of B material points:\n\n" + table(d["rev"], [
            ("points", "B"), ("n_theta", "nθ"), ("axial_pct", "to axial [%]"),
            ("dem_requests", "YADE requests"), ("seconds_dem", "DEM-REV [s]", fixed(1)),
            ("seconds_ann", "ANN-REV, compiled [ms]", scaled(1e3, 1)),
            ("seconds_teacher", "teacher, compiled [ms]", scaled(1e3, 1)),
            ("seconds_ann_generic", "ANN-REV, generic driver [ms]", scaled(1e3, 1)),
            ("dem_over_ann", "DEM / ANN", fixed(0)), ("dem_over_teacher", "DEM / teacher", fixed(0)),
            ("dem_over_ann_generic", "DEM / ANN (generic)", fixed(0)),
            ("network_rows_ann", "network rows"),
            ("dem_over_network_ann", "ceiling: DEM / network time", fixed(0)),
            ("dem_over_network_teacher", "ceiling, teacher", fixed(0)),
            ("q_max_dev_pct_of_peak_ann", "max \\|Δq\\| / max q [%]", fixed(2))])
    return out


def _shares(key):
    """The bands' shares ``key`` of a fabric (hmodel.rev.contacts.Fabric.as_dict) as one cell."""
    return lambda f: " / ".join(f"{b[key]:.2f}" for b in f["bands"]) if f else None


def _contact_fabric(d):  # model3d/contact_fabric.json
    bands = " / ".join(f"{lo:g}–{hi:g}°" for lo, hi in d["bands"])
    fab = [(lambda r: r["f"]["stress_ratio"], "σ11/σr", fixed(2)),
           (lambda r: r["f"]["tensor"][0][0], "F11", fixed(3)),
           (lambda r: r["f"]["force_tensor"][0][0], "F11 force-weighted", fixed(3)),
           (lambda r: _shares("contacts")(r["f"]), f"contacts, {bands}"),
           (lambda r: _shares("sig_axial")(r["f"]), "σ11"), (lambda r: _shares("sig_lateral")(r["f"]), "σr"),
           (lambda r: r["f"].get("distance_to_dem"), "distance to the DEM (contacts, σ11, σr)",
            lambda t: " / ".join(f"{t[k]:.2f}" for k in ("contacts", "sig_axial", "sig_lateral")) if t else "—")]
    rows = [{"what": f"DEM {r['sample']}, {s}", "q_p": r.get("q_p") if s == "final" else None,
             "eps_v": r.get("eps_v") if s == "final" else None, "f": r[s]}
            for r in d["dem"] for s in ("consolidated", "final")]
    rows += [{"what": f"REV α0 {r['alpha0']:g}°, {r['rule']}{'' if r['rule'] == 'off' else ' κ %g' % r['kappa']}, {s}",
              "q_p": r["q_p"] if s == "final" else None, "eps_v": r["eps_v"] if s == "final" else None, "f": r[s]}
             for r in d.get("rev", []) for s in ("consolidated", "final")]
    out = "The DEM samples and the sand variant's REV at the package's defaults (at 25 %: the final rows):\n\n"
    out += table(rows, [("what", ""), ("q_p", "q/p", fixed(3)), ("eps_v", "εv", fixed(3)), *fab]) + "\n"
    if d.get("judge"):
        judged = [{**r, "f": {**r["final"], "distance_to_dem": r["distance_to_dem"]} if "final" in r else None}
                  for r in d["judge"]]
        out += ("Each 3D variant at its DEM-judge calibration, drained at 100 kPa to 25 % from the sample's e0 "
                "(the fabric predicted; RMS \\|Δq\\|/peak q: the judge's record of the same test):\n\n")
        out += table(judged, [("variant", "variant"), ("sample", "sample"), ("alpha0_deg", "α0 [°]", fixed(1)),
                              ("q_p", "q/p", fixed(3)), ("eps_v", "εv", fixed(3)),
                              ("rms_dq_judge", "RMS \\|Δq\\|/peak q", scaled(100, 1)), ("failed", "failed"),
                              *[(lambda r, g=g: g(r) if r["f"] else None, h, *rest) for g, h, *rest in fab[1:]]])
    if d.get("swap"):
        swapped = [{**r, "f": {**r["final"], "distance_to_dem": r["distance_to_dem"]}} for r in d["swap"]]
        out += ("\nThe axisym and sand (axisym-mix) variants, each at its own DEM-judge calibration and at the "
                "other's (drained at 100 kPa to 25 %):\n\n")
        out += table(swapped, [("variant", "variant"), ("calibration", "calibration"), ("sample", "sample"),
                               ("alpha0_deg", "α0 [°]", fixed(1)), ("q_p", "q/p", fixed(3)), ("eps_v", "εv", fixed(3)),
                               *fab[1:]])
    if d.get("turn"):
        turned = [{**r, "f": {**r["final"], "distance_to_dem": r["distance_to_dem"]}} for r in d["turn"]]
        out += ("\nThe sand variant at the fabric probe's DEM-judge calibrations, the turning rule off and on "
                "(drained at 100 kPa to 25 %):\n\n")
        out += table(turned, [("rule", "rule"), ("kappa", "κ", fixed(1)), ("sample", "sample"),
                              ("alpha0_deg", "α0 [°]", fixed(1)), ("q_p", "q/p", fixed(3)), ("eps_v", "εv", fixed(3)),
                              *fab[1:]])
    return out


def _dem_ann_drift(d):
    out = settings({k: d[k] for k in ("model", "data") if k in d}) + "\n"
    groups: dict[str, list[float]] = {}
    for r in d["rows"]:
        if not _missing(r.get("max_dev_pct")):
            groups.setdefault(r.get("history", "?"), []).append(r["max_dev_pct"])
    summary = [{"h": h, "n": len(v), "lo": min(v), "hi": max(v)} for h, v in groups.items()]
    out += "Max \\|ΔVσ\\| relative to the history's largest \\|Vσ\\|, per history:\n\n" + table(summary, [
        ("h", "history"), ("n", "cells or paths"), ("lo", "smallest [%]", fixed(2)),
        ("hi", "largest [%]", fixed(2))])
    out += "\n??? note \"Every cell and path\"\n\n" + _indent(table(d["rows"], [
        ("history", "history"), ("theta_deg", "θ [°]", fixed(1)),
        ("max_dev_pct", "max \\|ΔVσ\\| [%]", fixed(2)), ("dem_max_vs", "largest \\|Vσ\\|")]))
    return out


def _dem_ann_start(d):
    out = settings({k: d[k] for k in ("model", "solver", "n_theta", "step") if k in d}) + "\n"
    if d.get("step_sensitivity"):
        out += "Max \\|Δq\\| / peak q over 1 % drained paths, by REV increment:\n\n" + table(
            d["step_sensitivity"], [("step", "REV increment"),
                                    ("q_max_dev_pct_of_peak_100kPa", "100 kPa [%]", fixed(2)),
                                    ("q_max_dev_pct_of_peak_200kPa", "200 kPa [%]", fixed(2))]) + "\n"
    if d.get("rows"):
        out += "Consolidation and the first shear increments:\n\n" + table(d["rows"], [
            ("p0_kPa", "p0 [kPa]"), ("stage", "stage"), ("eps11_pct", "ε11 [%]", fixed(4)),
            ("eps_v_dem_pct", "εv DEM [%]", fixed(4)), ("eps_v_ann_pct", "εv ANN [%]", fixed(4)),
            ("q_dem_kPa", "q DEM [kPa]", fixed(1)), ("q_ann_kPa", "q ANN [kPa]", fixed(1))]) + "\n"
    if d.get("first_step_linearity"):
        out += "Is the first shear increment linear in the strain? Σ δ(Vσ)/e as the tangent and " \
               "over the whole step:\n\n" + table(d["first_step_linearity"], [
                   ("p0_kPa", "p0 [kPa]"), ("sum_dVs_nn_tangent", "nn, tangent", fixed(3)),
                   ("sum_dVs_nn_whole_step", "nn, whole step", fixed(3)),
                   ("sum_dVs_tt_tangent", "tt, tangent", fixed(3)),
                   ("sum_dVs_tt_whole_step", "tt, whole step", fixed(3))])
    return out


def _indent(s: str) -> str:
    return "".join("    " + line + "\n" if line.strip() else "\n" for line in s.splitlines())


def _layout(d: dict):
    """The dedicated layout of a JSON file, after its structure; None for the generic one."""
    rows = d.get("rows") if isinstance(d.get("rows"), list) else []
    first = rows[0] if rows and isinstance(rows[0], dict) else {}
    if isinstance(d.get("results"), list) and d["results"] and "measure" in d["results"][0]:
        return _results
    if isinstance(d.get("generation"), list):
        return _data
    if isinstance(d.get("results"), list) and d["results"] and "metrics" in d["results"][0]:
        return _surrogate
    if "surrogate_over_closed_form" in first:
        return _ann_rev
    if "dem_over_ann" in first and "path" in first:
        return _dem_ann
    if isinstance(d.get("dem"), list) and "bands" in d:
        return _contact_fabric
    if isinstance(d.get("rev"), list) or isinstance(d.get("cell"), list):
        return _dem_ann_speed
    if "max_dev_pct" in first:
        return _dem_ann_drift
    if "step_sensitivity" in d:
        return _dem_ann_start
    return None


def render(name: str, path: Path, scripts: set[str]) -> str:
    """The provenance line and tables of one benchmark file, ``benchmarks/NAME.json``."""
    d = json.loads(path.read_text())
    if not isinstance(d, dict):
        log.warning("benchmarks page: benchmarks/%s.json is not a JSON object", name)
        return f"*benchmarks/{name}.json is not a record.*\n"
    head = f'<a id="{anchor(name)}"></a>' + provenance(name, path, d, scripts) + "\n"
    layout = _layout(d)
    if layout is not None:
        try:
            return head + layout(d)
        except (KeyError, TypeError, ValueError, AttributeError) as e:  # a changed structure
            log.info("benchmarks: generic layout for %s (%s)", path.name, e)
    return head + settings({k: v for k, v in d.items() if k not in PROVENANCE}) + "\n" + generic_tables(d)


def anchor(name: str) -> str:
    """The page anchor of ``benchmarks/NAME.json``'s tables (``engine/engine3d``:
    ``bench-engine-engine3d``)."""
    return "bench-" + re.sub(r"[^\w-]", "-", name)


def targets(found: dict[str, Path]) -> str:
    """The count of met and missed numeric targets over every file with a measure/value/target
    table, and a table of the missed ones linking to their file's tables."""
    met, missed = 0, []
    for name, path in found.items():
        try:
            d = json.loads(path.read_text())
        except (OSError, ValueError):
            continue  # said where the file's tables are placed
        if not isinstance(d, dict) or _layout(d) is not _results:
            continue
        for r in (r for r in d["results"] if isinstance(r, dict)):
            v = verdict(r.get("value"), r.get("target"))
            met += v == "met"
            if v == "missed":
                missed.append({"file": f"[`{name}`](#{anchor(name)})", "measure": r.get("measure"),
                               "value": _value(r), "target": r.get("target")})
    head = (f"Of the {met + len(missed)} measures whose target is a number, **{met} meet it and "
            f"{len(missed)} miss it**; each file's table says which in its *target met?* column. "
            "Targets in words (*small*, *the noise floor*, a figure of the report) are left to "
            "the reader.\n")
    if not missed:
        return head
    return head + f"\n???+ warning \"The {len(missed)} missed targets\"\n\n" + _indent(table(missed, [
        ("file", "file"), ("measure", "measure"), ("value", "value"), ("target", "target")]))


# --------------------------------------------------------------------------- MkDocs events

def _folder(config) -> Path:
    return Path(config["config_file_path"]).resolve().parent / "benchmarks"


def on_page_markdown(markdown, page, config, files, **kwargs):
    if page.file.src_uri != PAGE:
        return markdown
    folder = _folder(config)
    found = {f"{p.parent.name}/{p.stem}": p for p in sorted(folder.glob("*/*.json"))}
    scripts = {f"{p.parent.name}/{p.stem}" for p in folder.glob("*/*.py")}
    placed: set[str] = {m.group(1) for m in MARKER.finditer(markdown) if m.group(1) != "*"}

    def replace(m):
        name = m.group(1)
        if name == "*":
            rest = [n for n in found if n not in placed]
            return "\n".join(f"### `{n}.json`\n\n" + render(n, found[n], scripts) for n in rest) \
                or "(no other benchmark files)\n"
        if name not in found:
            log.warning("benchmarks page: no benchmarks/%s.json", name)
            return f"*benchmarks/{name}.json is missing.*\n"
        try:
            return render(name, found[name], scripts)
        except (OSError, ValueError) as e:
            log.warning("benchmarks page: cannot read benchmarks/%s.json: %s", name, e)
            return f"*benchmarks/{name}.json could not be read.*\n"

    markdown = markdown.replace(TARGETS, targets(found))
    return MARKER.sub(replace, markdown)


def on_serve(server, config, builder, **kwargs):
    server.watch(str(_folder(config)))
    return server
