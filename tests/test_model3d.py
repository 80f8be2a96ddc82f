"""The 3D model built in one place (hmodel.rev.model3d): the cell a solver makes, the parameters'
defaults, the 2D model's parameters refused; used alike by the Python tests, programs and the
command line, whose shared options live in hmodel.cli.options and hmodel.cli.common3d."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import typer

from hmodel.cell import ClosedFormSolver
from hmodel.cell.bihex import BiHexSolver
from hmodel.errors import InputError
from hmodel.loading import Program, run_triaxial
from hmodel.params import Params
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.model3d import (
    assignments_3d,
    cell_solver_3d,
    check_3d_param_sets,
    params_3d,
    sliding_rhs_3d,
)
from hmodel.solvers import get_solver, get_solver_3d
from hmodel.units import BARE_PRESSURE_MIN, parse_pressure, parse_pressures

SPHERE = Sphere(order=5, n_azimuth=1, axis=(1.0, 0.0, 0.0))
CLI = Path(__file__).resolve().parents[1] / "src" / "hmodel" / "cli"


class Trained(ClosedFormSolver):
    """The closed form declaring the material of a network it stands for."""

    name = "trained"

    def __init__(self, rhs: str):
        self.trained_params = {"sliding_rhs": rhs, "phi_g": 30.0}


def test_a_solver_makes_its_3d_cell():
    assert cell_solver_3d().closed_form and cell_solver_3d().name == "closed-form"
    wrapped = cell_solver_3d(ClosedFormSolver())
    assert isinstance(wrapped, BiHexSolver) and wrapped.closed_form
    assert cell_solver_3d(wrapped) is wrapped  # a 3D cell as it is
    assert isinstance(get_solver_3d("closed-form"), BiHexSolver)
    with pytest.raises(InputError, match="DEM cell solver"):
        cell_solver_3d(get_solver("dem:standard"))
    with pytest.raises(InputError, match="not a cell solver"):
        cell_solver_3d("closed-form")


def test_the_closed_form_given_as_its_2d_solver_runs_the_same_bihexagons():
    """A 2D closed-form solver given to a 3D test or program is the closed-form bi-hexagon: the
    same numbers as no solver (what the command line's ``closed-form`` gives)."""
    params = params_3d()
    a = run_triaxial(params, 2e5, 0.003, sphere=SPHERE, step=1e-3)
    b = run_triaxial(params, 2e5, 0.003, sphere=SPHERE, step=1e-3, solver=ClosedFormSolver())
    for name in ("eps11", "sig11", "sig22", "q", "eps_v"):
        np.testing.assert_array_equal(a[name], b[name])
    prog = Program.from_dict({"dim": 3, "sphere": {"order": 5, "azimuths": 1},
                              "stage": [{"preset": "iso", "p": "200kPa"},
                                        {"preset": "drained", "eps11": 0.002, "steps": 2}]})
    assert isinstance(prog.make_rev(params, ClosedFormSolver()).solver, BiHexSolver)
    c, d = prog.run(params), prog.run(params, ClosedFormSolver())
    np.testing.assert_array_equal(c["q"], d["q"])


def test_sliding_rhs_defaults_to_equilibrium_or_the_learned_cells_own():
    assert sliding_rhs_3d() == "equilibrium" == params_3d().sliding_rhs
    assert sliding_rhs_3d(Trained("report")) == "report"
    assert sliding_rhs_3d(BiHexSolver(hexagon=Trained("report"))) == "report"  # through the bi-hexagon
    assert params_3d(Trained("report")).sliding_rhs == "report"
    assert params_3d(sliding_rhs="report", kn=1e8).kn == 1e8
    assert assignments_3d(["phi_g=25"]) == ["sliding_rhs=equilibrium", "phi_g=25"]
    assert assignments_3d(["phi_g=25"], Trained("report"))[0] == "sliding_rhs=report"
    assert assignments_3d(["sliding_rhs=report"]) == ["sliding_rhs=report"]
    assert assignments_3d(None, base=Params()) == []  # a calibrated model keeps its own


def test_the_2d_models_parameters_are_refused_naming_their_3d_place():
    with pytest.raises(InputError, match="--param: parameter n_theta .*--order N"):
        assignments_3d(["n_theta=72"])
    with pytest.raises(InputError, match="-p of here: parameter alpha_omega .*--fabric A"):
        assignments_3d(["alpha_omega=0.3"], where="-p of here")
    with pytest.raises(InputError, match="parameter beta_omega"):
        check_3d_param_sets([Params(), Params(beta_omega=0.2)])
    check_3d_param_sets(Params(n_theta=12))  # unused in 3D, not refused


def test_python_tests_take_params_as_given_and_none_for_the_3d_defaults():
    """``Params()`` is the report's λ wherever it is given; ``None`` is the 3D model's defaults,
    the same numbers as the command line's."""
    none = run_triaxial(None, 2e5, 0.002, sphere=SPHERE, step=1e-3)
    explicit = run_triaxial(Params(sliding_rhs="equilibrium"), 2e5, 0.002, sphere=SPHERE, step=1e-3)
    assert none.meta["params"]["sliding_rhs"] == "equilibrium"
    np.testing.assert_array_equal(none["q"], explicit["q"])
    given = run_triaxial(Params(), 2e5, 0.002, sphere=SPHERE, step=1e-3)
    assert given.meta["params"]["sliding_rhs"] == "report"
    assert Rev3D(Params(), SPHERE).params.sliding_rhs == "report"


def test_a_3d_program_takes_the_3d_defaults_where_nothing_sets_sliding_rhs():
    stages = [{"preset": "iso", "p": "200kPa"}]
    prog = Program.from_dict({"dim": 3, "stage": stages})
    assert prog.with_params(None).sliding_rhs == "equilibrium"
    assert prog.with_params(None, solver=Trained("report")).sliding_rhs == "report"
    assert prog.with_params(["sliding_rhs=report"]).sliding_rhs == "report"
    assert prog.with_params(None, base=Params(kn=1e8)).sliding_rhs == "report"  # the base's own
    own = Program.from_dict({"dim": 3, "params": {"sliding_rhs": "report"}, "stage": stages})
    assert own.with_params(None).sliding_rhs == "report"
    assert Program.from_dict({"stage": stages}).with_params(None).sliding_rhs == "report"  # 2D
    with pytest.raises(InputError, match="--param of a 3D program: parameter n_theta"):
        prog.with_params(["n_theta=72"])


def test_bare_pressures_below_10_kpa_are_refused_where_typed():
    assert BARE_PRESSURE_MIN == 1e4
    assert parse_pressure("100") == 100.0  # the library's reader: Pa, as it always was
    assert parse_pressure("100Pa", "--p0") == 100.0  # a unit says what is meant
    assert parse_pressure("2e5", "--p0") == 2e5
    assert parse_pressures("100kPa, 1e4", "--p0") == [1e5, 1e4]
    with pytest.raises(InputError, match=r"^--p0 100 has no unit and would be 100 Pa: give its unit "
                                         r"\(100kPa, or 100Pa if Pa is meant\)$"):
        parse_pressure("100", "--p0")
    with pytest.raises(InputError, match="--p 9999 has no unit"):
        parse_pressures("200kPa,9999", "--p")


def _commands(group, path=()):
    """Every command of a group (Typer's own click: groups are told by their commands)."""
    for name, cmd in group.commands.items():
        if hasattr(cmd, "commands"):
            yield from _commands(cmd, (*path, name))
        else:
            yield " ".join((*path, name)), cmd


def test_every_strain_option_says_it_is_a_fraction():
    from hmodel.cli.app import app

    strains = {"axial_strain", "step", "iso_step", "max_step", "settlement", "max_strain"}
    seen = 0
    for name, cmd in _commands(typer.main.get_command(app)):
        for opt in cmd.params:
            if opt.name in strains and opt.param_type_name == "option":
                assert "a fraction: 0.01 is 1 %" in (opt.help or ""), f"{name} --{opt.name}"
                seen += 1
    assert seen > 20


def test_the_root_help_shows_whole_summaries():
    from typer.testing import CliRunner

    from hmodel.cli.app import app

    out = CliRunner().invoke(app, ["--help"]).output
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("reproduce"))
    assert "HTML report" in line and "(Fig." not in line


def test_no_command_module_imports_another():
    """The commands share their options through hmodel.cli.options and hmodel.cli.common3d; only
    the app imports the command modules."""
    shared = {"options", "common3d", "progress"}
    for path in CLI.glob("*.py"):
        if path.name in ("app.py", "__init__.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                assert node.module in shared, f"{path.name} imports .{node.module}"



def test_a_3d_program_runs_the_learned_cell_as_run_triaxial_does(tmp_path):
    """``run program`` of a 3D program takes ``--solver surrogate`` as ``run triaxial`` does: the
    shipped network of the equilibrium λ stepping the hexagons (it used to be refused by name),
    close to the closed-form bi-hexagon."""
    import csv

    from hmodel.cli.app import main

    prog = tmp_path / "small3d.toml"
    prog.write_text('dim = 3\n[sphere]\norder = 5\nazimuths = 1\n[[stage]]\npreset = "iso"\np = "200kPa"\n'
                    '[[stage]]\npreset = "drained"\neps11 = 0.002\nsteps = 4\n')
    q = {}
    for name, extra in (("cf", []), ("ann", ["--solver", "surrogate"])):
        assert main(["run", "program", str(prog), *extra, "--out", str(tmp_path / name)]) == 0
        q[name] = np.array([float(r["q"]) for r in csv.DictReader(open(tmp_path / name / "result.csv"))])
    assert len(q["cf"]) == len(q["ann"]) and q["cf"][-1] > 5e4
    assert np.abs(q["ann"] - q["cf"]).max() < 1e-4 * q["cf"].max()
