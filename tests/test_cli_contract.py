"""The command line's error contract on bad input (docs/cli.md, "Output and error contract"):
one line ``hmodel: error: ...``, exit status 1 (2 for a malformed command line), and nothing
written — for every case a new user was seen to hit (issue 31), and for random program files and
calibration data (Hypothesis)."""

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hmodel.calibrate import fit
from hmodel.calibrate.data import Test
from hmodel.calibrate.fitting import CalibrationFailed
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.cli.app import main
from hmodel.data import DatasetSpec, generate
from hmodel.errors import SolverError
from hmodel.limits import (
    WorkTooLarge,
    check_count,
    check_disk,
    check_memory,
    human_bytes,
    parse_bytes,
)
from hmodel.params import Params
from hmodel.surrogate.shipped import model_path

MODEL = str(model_path("shipped"))
ISO = '[[stage]]\npreset = "iso"\np = "200kPa"\n'
DRAINED = ISO + '[[stage]]\npreset = "drained"\n'

# name -> file contents (bytes or text), written into the case's folder before it runs
FILES = {
    "latin1.toml": b'[[stage]]\npreset = "iso"\np = "200kPa"\nname = "\xff"\n',
    "until_div0.toml": DRAINED + 'q = "p0"\nuntil = "q >= 1/0"\n',
    "target_div0.toml": DRAINED + 'q = "p0 / 0"\n',
    "iso_div0.toml": '[[stage]]\npreset = "iso"\np = "1/0"\n',
    "deep.toml": DRAINED + 'q = "p0"\nuntil = "q >= ' + "-" * 900 + '1"\n',
    "deep_short.toml": DRAINED + 'q = "p0"\nuntil = "q >= ' + "-" * 300 + '1"\n',
    "huge_steps.toml": DRAINED + "eps11 = 0.01\nsteps = 99999999999999999999999\n",
    "tiny_increment.toml": DRAINED + "eps11 = 0.01\nmax_increment = 1e-300\n",
    "billion_steps.toml": DRAINED + "eps11 = 0.01\nsteps = 1000000000\n",
    "wide_field.csv": "eps11,q,eps_v\n0.001," + "1" * 140_000 + ",0.0001\n0.002,2,0.0002\n",
    "wide_strain.csv": "eps11,eps22\n0.001," + "1" * 140_000 + "\n",
    "percent.csv": "eps11,q\n" + "".join(f"{0.01 * i},{1000 * i}\n" for i in range(1, 271)),
    "test.csv": "eps11,q,eps_v\n" + "".join(f"{0.001 * i},{2e4 * i},{1e-4 * i}\n" for i in range(1, 20)),
    "a_file": "not a folder\n",
    "rows3d_in_2d.toml": ISO + "[[stage]]\ncontrol = {eps11 = 0.01, eps33 = 0, eps12 = 0}\n",
    "rows2d_in_3d.toml": "dim = 3\n" + ISO + '[[stage]]\ncontrol = {eps11 = 0.01, sig22 = "hold", eps12 = 0}\n',
    "b_in_3d.toml": "dim = 3\n" + ISO + '[[stage]]\npreset = "true_triaxial"\nb = 1.5\neps11 = 0.01\n',
    "theta_in_3d.toml": "dim = 3\n[params]\nn_theta = 72\n" + ISO,
    "order_13.toml": "[sphere]\norder = 13\n" + ISO,
    "iso_3d.toml": "dim = 3\n" + ISO,
}
FAST = ["-p", "n_theta=12"]
CAL = ["calibrate", "--data", "drained:200kPa:test.csv", "--fit", "phi_g", "--starts", "1", *FAST]

# (id, command line, exit status, a phrase of the message)
CASES = [
    ("1 program not UTF-8", ["run", "program", "latin1.toml", "--out", "o"], 1, "not UTF-8"),
    ("1 stability program not UTF-8", ["stability", "--program", "latin1.toml", "--out", "o"], 1, "not UTF-8"),
    ("2 until 1/0", ["run", "program", "until_div0.toml", "--out", "o", *FAST], 1, "1 / 0 is not a finite"),
    ("2 target p0/0", ["run", "program", "target_div0.toml", "--out", "o", *FAST], 1, "not a finite stress"),
    ("2 iso p 1/0", ["run", "program", "iso_div0.toml", "--out", "o", *FAST], 1, "1 / 0 is not a finite"),
    ("3 deep until", ["run", "program", "deep.toml", "--out", "o", *FAST], 1, "at most 500"),
    ("3 deep short until", ["run", "program", "deep_short.toml", "--out", "o", *FAST], 1, "nested too deeply"),
    ("4 steps 1e23", ["run", "program", "huge_steps.toml", "--out", "o", *FAST], 1, "exceeds the limit"),
    ("4 max_increment 1e-300", ["run", "program", "tiny_increment.toml", "--out", "o", *FAST], 1,
     "exceeds the limit"),
    ("5 wide CSV field, calibrate", ["calibrate", "--data", "drained:200kPa:wide_field.csv", "--out", "o"], 1,
     "field larger than field limit"),
    ("5 wide CSV field, strain path", ["run", "strain-path", "wide_strain.csv", "--out", "o"], 1,
     "field larger than field limit"),
    ("6 fem mesh 1000x1000", ["fem", "biaxial", "--mesh", "1000x1000", "--out", "o"], 1, "of memory, over the limit"),
    ("6 fem mesh 1e20x1", ["fem", "biaxial", "--mesh", "100000000000000000000x1", "--out", "o"], 1,
     "of memory, over the limit"),
    ("7 n_theta 1e8", ["run", "biaxial", "-p", "n_theta=100000000", "--out", "o"], 1, "of memory, over the limit"),
    ("7 n_theta 1e30", ["run", "biaxial", "-p", "n_theta=1e30", "--out", "o"], 1, "of memory, over the limit"),
    ("8 calibrate step 1e-12", [*CAL, "--step", "1e-12", "--out", "o"], 1, "exceeds the limit"),
    ("9 calibrate iso-step inf", [*CAL, "--iso-step", "inf", "--out", "o"], 1, "positive finite"),
    ("9 calibrate step inf", [*CAL, "--step", "inf", "--out", "o"], 1, "positive finite"),
    ("9 calibrate eps11 in percent", ["calibrate", "--data", "drained:200kPa:percent.csv", "--out", "o"], 1,
     "must stay below 1"),
    ("10 evaluate rows 0", ["surrogate", "evaluate", MODEL, "--data", "nowhere", "--rows", "0", "--out", "o"], 2,
     "'--rows'"),
    ("10 evaluate rows -5", ["surrogate", "evaluate", MODEL, "--data", "nowhere", "--rows", "-5", "--out", "o"], 2,
     "'--rows'"),
    ("10 trust rows -3", ["surrogate", "trust", MODEL, "nowhere", "--rows", "-3", "--out", "o/m.safetensors"], 2,
     "'--rows'"),
    ("10 trust empty sample", ["surrogate", "trust", MODEL, "", "--out", "o/m.safetensors"], 1, "SAMPLE is empty"),
    ("11 sweep test 0", ["surrogate", "sweep", "nowhere", "--test", "0", "--out", "o/w"], 2, "'--test'"),
    ("12 out in /proc", ["run", "iso", *FAST, "--out", "/proc/hmodel-contract/x"], 1, "cannot write"),
    ("12 out under a file", ["run", "iso", *FAST, "--out", "a_file/x"], 1, "is not a folder"),
    ("12 out under a file, calibrate", [*CAL, "--out", "a_file/x"], 1, "is not a folder"),
    ("12 out under a file, fem", ["fem", "biaxial", "--out", "a_file/x"], 1, "is not a folder"),
    ("12 out under a file, program", ["run", "program", "huge_steps.toml", "--out", "a_file/x"], 1,
     "is not a folder"),
    ("13 trust out is a folder", ["surrogate", "trust", MODEL, "nowhere", "--out", "folder.safetensors"], 1,
     "is a folder"),
    ("judgement: fitted and fixed", [*CAL, "-p", "phi_g=30", "--out", "o"], 1, "both fitted"),
    ("judgement: empty out", ["run", "iso", *FAST, "--out", ""], 2, "the path is empty"),
    ("judgement: program steps 1e9", ["run", "program", "billion_steps.toml", "--out", "o", *FAST], 1,
     "exceeds the limit"),
    ("database of 1e14 rows", ["data", "generate", "2", "--directions", "1000000000", "--out", "o"], 1,
     "of disk"),
    ("stability with 1e8 probes", ["stability", "--probes", "100000000", *FAST, "--out", "o"], 1,
     "of memory, over the limit"),
    ("judgement: fem steps 1e20", ["fem", "biaxial", "--steps", "100000000000000000000", "--out", "o"], 1,
     "exceeds the limit"),
    # 3D tests (issue 34)
    ("3D unknown rule order", ["run", "triaxial", "--order", "13", "--out", "o"], 1, "Lebedev rule order must be one of"),
    ("3D unknown rule order, program", ["run", "program", "order_13.toml", "--out", "o"], 1, "Lebedev rule order"),
    ("3D b above 1", ["run", "true-triaxial", "--b", "1.5", "--out", "o"], 2, "'--b'"),
    ("3D b below 0", ["run", "true-triaxial", "--b", "-0.1", "--out", "o"], 2, "'--b'"),
    ("3D b above 1, program", ["run", "program", "b_in_3d.toml", "--out", "o"], 1, "b must be a number in [0, 1]"),
    ("3D azimuths 0", ["run", "triaxial", "--azimuths", "0", "--out", "o"], 2, "'--azimuths'"),
    ("3D fabric 2", ["run", "oedometer", "--fabric", "2", "--out", "o"], 2, "'--fabric'"),
    ("3D given n_theta", ["run", "triaxial", "-p", "n_theta=72", "--out", "o"], 1, "--order N"),
    ("3D given alpha_omega", ["run", "true-triaxial", "-p", "alpha_omega=0.3", "--out", "o"], 1, "--fabric A"),
    ("3D given beta_omega", ["run", "oedometer", "-p", "beta_omega=10", "--out", "o"], 1, "the axial axis 1"),
    ("3D program given n_theta", ["run", "program", "theta_in_3d.toml", "--out", "o"], 1, "[sphere] order"),
    ("3D program given -p n_theta", ["run", "program", "iso_3d.toml", "-p", "n_theta=72", "--out", "o"], 1,
     "[sphere] order"),
    ("3D row in a 2D program", ["run", "program", "rows3d_in_2d.toml", "--out", "o"], 1, "a 3D program says dim = 3"),
    ("2D rows in a 3D program", ["run", "program", "rows2d_in_3d.toml", "--out", "o"], 1,
     "component 23 is not controlled"),
    ("2D test given a 3D option", ["run", "biaxial", "--order", "9", "--out", "o"], 2, "--order"),
    ("failure surface Lode 75", ["failure-surface", "--lode", "0,75", "--out", "o"], 1,
     "a Lode angle must lie in [0, 60]"),
    ("failure surface Lode -5", ["failure-surface", "--lode", "-5", "--out", "o"], 1, "[0, 60]"),
    ("failure surface Lode not a number", ["failure-surface", "--lode", "0,abc", "--out", "o"], 1,
     "--lode must be Lode angles"),
    ("failure surface two pressures", ["failure-surface", "--p", "100kPa,200kPa", "--out", "o"], 1,
     "one mean stress"),
    ("failure surface parameter lists", ["failure-surface", "-p", "phi_g=25,35", "--out", "o"], 1,
     "one parameter set"),
    ("failure surface given n_theta", ["failure-surface", "-p", "n_theta=72", "--out", "o"], 1, "--order N"),
    ("failure surface unknown order", ["failure-surface", "--order", "25", "--out", "o"], 1, "Lebedev rule order"),
    ("stability of a 3D program given --order", ["stability", "--program", "iso_3d.toml", "--order",
                                                  "9", "--out", "o"], 1, "does not apply with --program"),
    ("stability of a 3D test given n_theta", ["stability", "--test", "triaxial", "-p", "n_theta=72",
                                              "--out", "o"], 1, "--order N"),
    ("3D hexagon-consistent volume", ["run", "triaxial", "-p", "volume=hexagon-consistent", "--out", "o"], 1,
     "hexagon, rectangle, box for the 3D H-model"),
]


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _prepare(folder: Path) -> None:
    for name, content in FILES.items():
        (folder / name).write_bytes(content if isinstance(content, bytes) else content.encode())
    (folder / "folder.safetensors").mkdir()


def run_case(args, folder: Path, capsys) -> tuple[int, str, set[str]]:
    """Run ``hmodel args`` in ``folder``; the exit status, stderr, and the paths it added."""
    before = _tree(folder)
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        code = main([str(a) for a in args])
    finally:
        os.chdir(cwd)
    _, err = capsys.readouterr()
    return code, err, _tree(folder) - before


@pytest.mark.parametrize("args, status, phrase", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, status, phrase):
    _prepare(tmp_path)
    code, err, added = run_case(args, tmp_path, capsys)
    assert code == status, err
    assert err.startswith("hmodel: error: ") and err.count("\n") == 1, err
    assert phrase in err, err
    assert not added, added


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    spec = DatasetSpec(kind=2, n_directions=3, alpha0_min=40, alpha0_max=50, alpha0_step=10, max_strain=0.01)
    out = tmp_path_factory.mktemp("d") / "d2"
    generate(spec, Params(), out)
    return out


def test_sweep_refused_leaves_no_partial_file(tmp_path, capsys, dataset):
    """Case 14: --depths abc was refused after the sweep's resume file had been written."""
    code, err, added = run_case(["surrogate", "sweep", dataset, "--depths", "abc", "--out", "o/w4"],
                                tmp_path, capsys)
    assert code == 1 and "--depths" in err and not added, (err, added)


def test_training_a_network_too_large_for_the_memory(tmp_path, capsys, tiny_model):
    """A 100 x 10^8 network used to be a PyTorch allocation traceback."""
    sample = tiny_model[1] / "sample"
    code, err, added = run_case(["surrogate", "train", sample, "--width", "100000000", "--depth", "100",
                                 "--out", "o/m.safetensors"], tmp_path, capsys)
    assert code == 1 and "network needs about" in err and err.count("\n") == 1 and not added, err


def test_a_genuine_bug_keeps_its_traceback(monkeypatch):
    """The boundary turns input and environment errors into one line, not bugs."""
    import hmodel.cli.run as run_cmds

    def broken(*a, **k):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(run_cmds, "run_isotropic", broken)
    with pytest.raises(ZeroDivisionError):
        main(["run", "iso", *FAST, "--out", "never"])


def test_debug_shows_the_stack_of_an_input_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HMODEL_DEBUG", "1")
    with pytest.raises(WorkTooLarge):
        main(["run", "biaxial", "-p", "n_theta=100000000", "--out", str(tmp_path / "o")])


def test_environment_errors_are_one_line(monkeypatch, capsys, tmp_path):
    import hmodel.cli.run as run_cmds

    def full_disk(*a, **k):
        raise OSError(28, "No space left on device", "result.csv")

    monkeypatch.setattr(run_cmds, "write_outputs", full_disk)
    assert main(["run", "iso", *FAST, "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err == "hmodel: error: No space left on device: 'result.csv'\n"


# ---------------------------------------------------------------- the work-size guard itself

def test_memory_guard_refuses_above_the_budget_and_names_both():
    check_memory(2**20, "a small request", env={"HMODEL_MEMORY_LIMIT": "1MiB"})  # at the limit
    with pytest.raises(WorkTooLarge, match=r"a big request needs about 1\.5 MiB of memory, over the "
                                           r"limit of 1 MiB \(HMODEL_MEMORY_LIMIT\)"):
        check_memory(1.5 * 2**20, "a big request", env={"HMODEL_MEMORY_LIMIT": "1MiB"})
    with pytest.raises(WorkTooLarge):
        check_memory(float("nan"), "an overflowed estimate", env={"HMODEL_MEMORY_LIMIT": "1GiB"})


def test_memory_guard_default_is_half_the_available_memory(monkeypatch):
    import hmodel.limits as limits

    monkeypatch.setattr(limits, "available_memory", lambda: 8 * 2**30)
    check_memory(4 * 2**30, "half", env={})
    with pytest.raises(WorkTooLarge, match="half the available memory"):
        check_memory(4 * 2**30 + 1, "more than half", env={})


def test_sizes_parse_and_print():
    assert parse_bytes("500MB") == 500_000_000 and parse_bytes("2GiB") == 2 * 2**30 and parse_bytes("123") == 123
    assert human_bytes(85.8 * 2**30) == "85.8 GiB" and human_bytes(12) == "12 B"
    for bad in ("", "lots", "-1GB", "1XB", "inf"):
        with pytest.raises(Exception, match="HMODEL_MEMORY_LIMIT"):
            parse_bytes(bad)


def test_disk_guard_against_the_free_space(tmp_path):
    import shutil

    free = shutil.disk_usage(tmp_path).free
    check_disk(free // 2, tmp_path / "not" / "yet", "half the free space")
    with pytest.raises(WorkTooLarge, match="of disk, and .* free"):
        check_disk(2 * free, tmp_path / "not" / "yet", "twice the free space")
    assert not (tmp_path / "not").exists()


def test_training_memory_counts_the_networks_parameters():
    """The estimate's parameter count is the torch network's own (an independent count)."""
    pytest.importorskip("torch")
    from hmodel.surrogate.model import Architecture
    from hmodel.surrogate.training import build_network, training_bytes

    arch = Architecture(64, 3, "silu")
    n = sum(p.numel() for p in build_network(arch, 4, 24).parameters())
    assert training_bytes(arch, 4, 24, batch_size=0) == 16 * n  # float32, four copies
    assert training_bytes(arch, 4, 24, batch_size=1024) == 16 * n + 4 * 2 * 1024 * 64 * 3


def test_count_guard_and_its_override():
    assert check_count(10**7, "n", env={}) == 10**7
    with pytest.raises(WorkTooLarge, match="1e\\+07"):
        check_count(10**7 + 1, "n", env={})
    with pytest.raises(WorkTooLarge, match="unbounded"):
        check_count(math.inf, "n", env={})
    assert check_count(5, "n", env={"HMODEL_MAX_INCREMENTS": "5"}) == 5
    with pytest.raises(WorkTooLarge):
        check_count(6, "n", env={"HMODEL_MAX_INCREMENTS": "5"})


def test_rev_guard_counts_points_directions_and_the_solvers_bytes(monkeypatch):
    """The REV's estimate is points × directions × the solver's bytes per cell: a request just
    above the budget is refused, one just below is not."""
    from hmodel.rev import Rev

    cells = 4 * 90
    budget = cells * ClosedFormSolver.bytes_per_cell
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(budget))
    rev = Rev(Params(n_theta=90))
    rev.initial(4)
    with pytest.raises(WorkTooLarge, match="5 material points"):
        rev.initial(5)


class AlwaysFails(ClosedFormSolver):
    """A cell solver for which no parameter set can be run."""

    name = "always-fails"

    def kernel(self, params):
        return None

    def step(self, params, state, dl1, dl2):
        raise SolverError("no cell can be solved")


def test_a_calibration_in_which_every_evaluation_failed_is_an_error():
    e = np.linspace(0.001, 0.01, 5)
    with pytest.raises(CalibrationFailed, match="every one of the .* parameter sets evaluated failed"):
        fit([Test("drained", 1e5, e, 1e5 * e)], ("phi_g",), base=Params(n_theta=12), solver=AlwaysFails(),
            starts=1)


# ---------------------------------------------------------------- random input (Hypothesis)

def _contract(code: int, err: str, added: set[str]) -> None:
    assert code in (0, 1, 2), (code, err)
    if code:
        assert err.startswith("hmodel: error: ") and err.count("\n") == 1, err
        assert not added, added


_RANDOM = settings(max_examples=40, deadline=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
_WORDS = ["p0", "q", "p", "eps11", "eps_v", "q_p", "1/0", "0", "-", "+", "*", "/", "(", ")", ">=", "<",
          "150kPa", "abs(", "1e308", "9" * 30, "nan", "inf", "__import__", ".", ",", " "]
_values = st.recursive(
    st.one_of(st.integers(-10**25, 10**25), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
              st.lists(st.sampled_from(_WORDS), max_size=8).map("".join),
              st.sampled_from(["iso", "drained", "undrained", "proportional", "hold", "200kPa", "0.5 * p0"])),
    lambda inner: st.lists(inner, max_size=3), max_leaves=6)
_KEYS = ["name", "preset", "p", "q", "sig22", "eps11", "eps22", "eps12", "sig12", "eps_v", "steps",
         "max_increment", "until", "repeat", "stop_on_failure", "direction", "magnitude", "other"]
_expression = st.lists(st.sampled_from(["p0", "0", "1", "0.5", "150kPa", "1/0", "/", "*", "-", "+", "(", ")",
                                         "abs(", "1e308", "9" * 400]), min_size=1, max_size=6).map(" ".join)
_criterion = st.tuples(st.sampled_from(["q", "p", "eps11", "q_p", "p0"]), st.sampled_from([">=", "<", "=="]),
                       _expression).map(" ".join)
# stages near the valid ones, where the expressions are read and evaluated, or anything at all
_stage = st.one_of(
    st.fixed_dictionaries({"preset": st.sampled_from(["drained", "undrained"]), "q": _expression},
                          optional={"until": _criterion, "steps": st.integers(-2, 10**25),
                                    "max_increment": st.floats(allow_nan=True, allow_infinity=True)}),
    st.dictionaries(st.sampled_from(_KEYS), _values, max_size=5))


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _toml(stages: list[dict], params: dict) -> str:
    text = "[params]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in params.items())
    for s in stages:
        text += "[[stage]]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in s.items())
    return text


@pytest.fixture
def bounded(monkeypatch):
    """Random programs that happen to be valid run small."""
    monkeypatch.setenv("HMODEL_MAX_INCREMENTS", "300")


@_RANDOM
@given(data=st.binary(max_size=400))
def test_random_bytes_as_a_program(tmp_path_factory, capsys, bounded, data):
    folder = tmp_path_factory.mktemp("bytes")
    (folder / "p.toml").write_bytes(data)
    _contract(*run_case(["run", "program", "p.toml", "--out", "o", *FAST], folder, capsys))


@_RANDOM
@given(stages=st.lists(_stage, min_size=0, max_size=3),
       params=st.dictionaries(st.sampled_from(["alpha0", "phi_g", "n_theta", "kn", "bogus"]), _values, max_size=2))
@pytest.mark.slow
def test_random_toml_programs(tmp_path_factory, capsys, bounded, stages, params):
    folder = tmp_path_factory.mktemp("toml")
    (folder / "p.toml").write_text(_toml([{"preset": "iso", "p": "200kPa"}] + stages, params))
    _contract(*run_case(["run", "program", "p.toml", "--out", "o", *FAST], folder, capsys))


_cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10**30, 10**30).map(str),
                  st.text(alphabet='ab,;"\n\r\x00 -.eE01', max_size=6))


@_RANDOM
@given(header=st.lists(st.sampled_from(["eps11", "q", "eps_v", "p", "x", ""]), min_size=0, max_size=4),
       rows=st.lists(st.lists(_cell, min_size=0, max_size=4), max_size=6))
def test_random_calibration_data(tmp_path_factory, capsys, bounded, header, rows):
    folder = tmp_path_factory.mktemp("csv")
    (folder / "d.csv").write_text("\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n")
    _contract(*run_case(["calibrate", "--data", "drained:200kPa:d.csv", "--fit", "phi_g", "--starts", "1",
                         "--out", "o", *FAST], folder, capsys))
