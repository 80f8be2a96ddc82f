"""What the figures and the reproduce report say: a program's stages, the comparison's error
panel on a round-off path, Fig. 1.7's cell events, and the report's tables and captions."""

from __future__ import annotations

import numpy as np

from hmodel import Params
from hmodel.compare import ERROR_AXIS_Q, overlay_figure
from hmodel.loading import Program, run_biaxial, standard_paths
from hmodel.loading.result import COLUMNS, PathResult
from hmodel.plotting import program_figure
from hmodel.studies import reproduce as rp

P = Params(n_theta=36)


def _unload_reload() -> PathResult:
    prog = Program.from_dict({"name": "loop", "stage": [
        {"preset": "iso", "p": "200kPa"},
        {"name": "load", "preset": "drained", "q": "0.6 * p0", "steps": 20},
        {"name": "unload", "preset": "drained", "q": "0.1 * p0", "steps": 10},
        {"name": "reload", "preset": "drained", "q": "0.6 * p0", "steps": 10}]})
    return prog.run(P)


def test_program_figure_names_its_stages_and_keeps_the_consolidation():
    res = _unload_reload()
    res.meta["file"] = "my-loop.toml"
    fig = program_figure(res)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    n_cons = int((res["stage"] == "consolidation").sum())
    assert [lab.split(" (")[0] for lab in labels] == ["consolidation", "load", "unload", "reload"]
    assert labels[0] == f"consolidation (rows 1–{n_cons})"
    by_row = fig.axes[2]  # the mean stress by row of result.csv, from its first row
    assert min(np.min(line.get_xdata()) for line in by_row.get_lines()) == 1
    # the unloading and reloading retrace the loading's stress path: drawn in their own colours,
    # narrower than the stage before them, so that each stays visible on top of the other
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    load, unload, reload = (next(v for k, v in lines.items() if k.startswith(n + " ("))
                            for n in ("load", "unload", "reload"))
    assert len({load.get_color(), unload.get_color(), reload.get_color()}) == 3
    assert load.get_linewidth() > unload.get_linewidth() > reload.get_linewidth()
    assert fig.get_suptitle().startswith("H-model, program my-loop.toml (loop)\n")
    res.meta.pop("file")  # a result without its file: the program's name
    assert program_figure(res).get_suptitle().startswith("H-model, program loop\n")


def _iso(q_noise: float) -> PathResult:
    """An isotropic compression: q is round-off only."""
    n = 8
    p, ev = np.linspace(2e4, 4e5, n), np.linspace(1e-4, 3e-3, n)
    q = q_noise * np.sin(np.arange(n))
    cols = {c: np.zeros(n) for c in COLUMNS}
    cols.update(point=np.zeros(n, int), stage=np.array(["consolidation"] * n, dtype=object),
                step=np.arange(1, n + 1), eps11=ev / 2, eps22=ev / 2, sig11=p + q / 2, sig22=p - q / 2,
                p=p, q=q, eps_v=ev)
    return PathResult(cols)


def test_isotropic_error_panel_is_relative_to_peak_p_on_a_readable_scale():
    """Round-off q (1e-10 Pa) divided by its own peak filled the panel with ±100 % noise; the
    panel now divides by peak p, as the table does, and keeps at least ±ERROR_AXIS_Q %."""
    fig = overlay_figure("isotropic", _iso(1e-10), _iso(-1e-10), ("closed form", "surrogate"))
    err = fig.axes[3]
    lo, hi = err.get_ylim()
    assert "peak p" in err.get_ylabel()
    assert lo <= -ERROR_AXIS_Q and hi >= ERROR_AXIS_Q and hi < 1.0
    worst = max(np.abs(line.get_ydata()).max() for line in err.get_lines())
    assert worst < 1e-12  # 2e-10 Pa over 4e5 Pa, in %
    assert any("max |Δq| / peak p" in t.get_text() for t in err.texts)


def test_fig17_caption_says_what_its_drops_are():
    """The drops of q before the peak are cells opening (report λ); none with the equilibrium λ."""
    res = run_biaxial(Params(), [1e5], 0.002)
    events = rp._cell_events(res)
    assert events and all(e["dq"] < 0 for e in events)
    first = events[0]
    assert first["opened"] > 0 and 0.5 < first["q_p"][0] < 0.6
    text = rp._fig17_caption(res)
    assert "cell events" in text and "sliding_rhs=equilibrium" in text and f"{first['opened']} of 360" in text
    smooth = run_biaxial(Params(sliding_rhs="equilibrium"), [1e5], 0.002)
    assert rp._cell_events(smooth) == [] and "cell events" not in rp._fig17_caption(smooth)


def test_report_pieces_read_as_text():
    from hmodel.data import DatasetSpec

    table = rp._options_table(DatasetSpec(kind=2).to_dict(), rp.DATASET_OPTIONS)
    assert "{'" not in table and "<td>--directions</td><td>91</td>" in table
    assert rp._surrogate_text("surrogate", "compliance", False) == "the shipped surrogate, compliance formulation"
    assert "surrogate surrogate" not in rp._surrogate_text("surrogate:increment", "increment", False)
    rows = [{"path": "isotropic", "in report": True, "speed ratio": 0.25},
            {"path": "rotation", "in report": False, "speed ratio": 0.11}]
    shown = rp._comparison_rows(rows)
    assert shown[0]["in the report (§3.1)"] == "yes" and shown[1]["in the report (§3.1)"] == "no"
    assert "in report" in rows[0]  # deviations.csv keeps its column
    assert "0.11–0.25" in rp._speed_text(rows) and "without a closed form" in rp._speed_text(rows)
    cap = rp._compare_caption(next(s for s in standard_paths() if s.name == "isotropic"))
    assert "peak mean stress" in cap and not cap.endswith(".png")


def test_a_figure_title_names_the_contact_law_it_ran_with():
    from hmodel.plotting import _subtitle

    def title(**params):
        return _subtitle(PathResult({"step": np.zeros(1)}, {"params": Params(**params).to_dict()}))

    linear, hertz = title(), title(contact="hertz-mindlin", renewal="rebirth")
    assert "kn=" in linear and "shear_modulus" not in linear and "Hertz" not in linear
    # kn and kt/kn are not read with Hertz-Mindlin contacts: G and nu are, and the mechanisms are named
    assert "kn=" not in hertz and "kt_kn" not in hertz
    assert "shear_modulus=2.9e+10" in hertz and "poisson=0.2" in hertz
    assert "Hertz–Mindlin contacts" in hertz and "cells reborn" in hertz


def test_a_3d_figure_title_names_the_sand_variants_mechanisms_and_its_sides():
    from hmodel.plotting import _subtitle

    sphere = {"order": 23, "n_azimuth": 6, "alpha_omega": 0.0}

    def title(meta=None, **params):
        return _subtitle(PathResult({"step": np.zeros(1)}, {"params": Params(**params).to_dict(), **(meta or {})}))

    sand = title({"sphere": sphere, "radial": "equal"}, contact="hertz-mindlin", renewal="mix", lateral="axisymmetric")
    assert "cells reborn at the mean box" in sand and "lateral strain about the cell's axis" in sand
    assert "one radial strain" in sand
    published = title({"sphere": sphere})
    assert "reborn" not in published and "lateral" not in published and "radial" not in published
    # in 2D the H-cell's one lateral length is either value: nothing to name
    assert "lateral" not in title(lateral="axisymmetric")
