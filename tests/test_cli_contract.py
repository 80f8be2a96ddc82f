"""The command line's error contract on bad input (docs/cli.md, "Output and error contract"):
one line ``hmodel: error: ...``, exit status 1 (2 for a malformed command line), and nothing
written — for every case a new user was seen to hit, and for random program files and
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
    # files of the size cases below
    "azimuths_1e9.toml": "[sphere]\nazimuths = 1000000000\n" + ISO,
    "rows_2e6.toml": DRAINED + "eps11 = 0.01\nsteps = 2000000\n",
    "long_stage_name.toml": ISO + '[[stage]]\nname = "' + "n" * 10_000 + '"\npreset = "drained"\neps11 = 0.01\n',
    "long_block_name.toml": ISO + '[[stage]]\nrepeat = 2\nstages = [{name = "' + "n" * 201
                            + '", preset = "drained", eps11 = 0.01}]\n',
    "long_key.toml": ISO + "[[stage]]\n" + "k" * 10_000 + ' = 1\npreset = "drained"\neps11 = 0.01\n',
    "long_param.toml": '[params]\nvolume = "' + "v" * 10_000 + '"\n' + ISO,
    # files of the expression cases below
    "expr_q_div0.toml": DRAINED + 'q = "p0 / (p0 - p0)"\n',
    "expr_sig22_div0.toml": ISO + '[[stage]]\ncontrol = {eps11 = 0.01, sig22 = "p0 / (p0 - p0)", eps12 = 0}\n',
    "expr_until_overflow.toml": DRAINED + 'q = "p0"\nuntil = "q >= 1e308 * 1e308"\n',
    "expr_q_div0_3d.toml": "dim = 3\n[sphere]\norder = 9\nazimuths = 2\n" + DRAINED
                           + 'q = "p0 / (p0 - p0)"\n',
    "expr_sig22_div0_3d.toml": "dim = 3\n[sphere]\norder = 9\nazimuths = 2\n" + ISO
                               + '[[stage]]\ncontrol = {eps11 = 0.01, sig22 = "p0 / (p0 - p0)", sig33 = "hold", '
                                 'eps23 = 0, eps13 = 0, eps12 = 0}\n',
    "expr_until_overflow_3d.toml": "dim = 3\n[sphere]\norder = 9\nazimuths = 2\n" + DRAINED
                                   + 'q = "p0"\nuntil = "lode >= 1e308 * 1e308"\n',
    "expr_abs.toml": DRAINED + 'eps11 = 0.01\nuntil = "q >= abs"\n',
    # files of the output, file and option cases below
    "bom_strain.csv": "\ufeffeps11,eps22\n0.001,abc\n",  # a spreadsheet's "CSV UTF-8": the header reads
    "bom_test.csv": "\ufeffeps11,q\n0.001,abc\n0.002,3\n",
    # files of the calibration cases below
    "percent_small.csv": "eps11,q\n" + "".join(f"{0.01 * i:.2f},{1000 * i}\n" for i in range(1, 97)),
    "q_kpa.csv": "eps11,q,eps_v\n" + "".join(f"{0.001 * i},{20 * i},{1e-4 * i}\n" for i in range(1, 20)),
    "t3.csv": "eps_a,q,eps_v\n" + "".join(f"{0.001 * i},{2e4 * i},{1e-4 * i}\n" for i in range(1, 20)),
    # files of the fem and failure-surface cases below
}
FAST = ["-p", "n_theta=12"]
T3 = ["run", "triaxial", "--order", "9", "--azimuths", "2", "--axial-strain", "0.01"]
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
    # 3D tests
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
    # sizes counted before anything is built
    ("size: triaxial azimuths 1e23", ["run", "triaxial", "--order", "9", "--azimuths", "99999999999999999999999",
                                      "--axial-strain", "0.01", "--out", "o"], 1,
     "1.9e+24 bi-hexagons (Lebedev order 9) needs about"),
    ("size: triaxial azimuths 1e9", ["run", "triaxial", "--order", "9", "--azimuths", "1000000000",
                                     "--axial-strain", "0.01", "--out", "o"], 1,
     "19,000,000,000 bi-hexagons (Lebedev order 9) needs about"),
    ("size: program azimuths 1e9", ["run", "program", "azimuths_1e9.toml", "--out", "o"], 1,
     "97,000,000,000 bi-hexagons (Lebedev order 23) needs about"),
    ("size: triaxial 30,000 pressures", [*T3, "--p0", ",".join(f"{100 + i / 100:.2f}kPa" for i in range(30_000)),
                                         "--out", "o"], 1,
     "30,000 material points × 101 rows: a result table of 3.03e+06 rows exceeds the limit of 1e+06 rows"),
    ("size: triaxial 40,000 friction angles", [*T3, "-p", "phi_g=" + ",".join(f"{20 + i / 2000:.4f}"
                                                                              for i in range(40_000)),
                                               "--out", "o"], 1, "a result table of 4.04e+06 rows exceeds"),
    ("size: biaxial 40,000 friction angles", ["run", "biaxial", "-p", "phi_g=" + ",".join(
        f"{20 + i / 2000:.4f}" for i in range(40_000)), "--out", "o"], 1, "a result table of 4e+07 rows exceeds"),
    ("size: program of 2e6 increments", ["run", "program", "rows_2e6.toml", "--out", "o", *FAST], 1,
     "the program's increments: a result table of 2e+06 rows exceeds the limit"),
    ("size: program read from /dev/zero", ["run", "program", "/dev/zero", "--out", "o"], 1,
     "is longer than 10,000,000 characters"),
    ("size: stage name of 10,000 characters", ["run", "program", "long_stage_name.toml", "--out", "o", *FAST], 1,
     "stage 2: name is 10,000 characters long; a name or text of a program has at most 200"),
    ("size: cycle's stage name of 201 characters", ["run", "program", "long_block_name.toml", "--out", "o",
                                                    *FAST], 1, "stage 2: stages 1: name is 201 characters"),
    ("size: key of 10,000 characters", ["run", "program", "long_key.toml", "--out", "o", *FAST], 1,
     "a key of stage 2 is 10,000 characters long"),
    ("size: parameter text of 10,000 characters", ["run", "program", "long_param.toml", "--out", "o"], 1,
     "params: volume is 10,000 characters long"),
    ("size: triaxial probes 1e9", ["stability", "--test", "triaxial", "--order", "9", "--azimuths", "2",
                                   "--axial-strain", "0.01", "--probes", "1000000000", "--out", "o"], 1,
     "1,000,000,000 probes of 38 bi-hexagons needs about"),
    ("size: biaxial probes 1e9", ["stability", "--axial-strain", "0.01", "--probes", "1000000000", "--out",
                                  "o"], 1, "1,000,000,000 probes of"),
    ("size: dem validate 3D steps 1e8", ["dem", "validate", "--dim", "3", "--steps", "100000000", "--out", "o"],
     1, "increments per path (--steps): 1e+08 exceeds the limit"),
    ("size: dem validate 3D steps 9e6", ["dem", "validate", "--dim", "3", "--steps", "9000000", "--out", "o"],
     1, "7 DEM bi-hexagon paths of 9,000,000 increments (each run with and without cross contacts) needs"),
    ("size: dem validate 2D steps 1e8", ["dem", "validate", "--steps", "100000000", "--out", "o"], 1,
     "increments per path (--steps): 1e+08 exceeds the limit"),
    ("size: dem validate 2D steps 9e6", ["dem", "validate", "--steps", "9000000", "--out", "o"], 1,
     "4 DEM cell paths of 9,000,000 increments and 8 probes"),
    ("size: dem validate 2D probes 1e9", ["dem", "validate", "--probes", "1000000000", "--out", "o"], 1,
     "(8,000,000,004 cells in one YADE scene) needs"),
    ("size: dem draw steps 1e9", ["dem", "draw", "--steps", "1000000000", "--out", "o"], 1,
     "increments (--steps): 1e+09 exceeds the limit"),
    ("size: dem sample spheres 1e9", ["dem", "sample", "--dim", "3", "--spheres", "1000000000", "--out", "o"], 1,
     "a test of 1,000,000,000 spheres (--spheres) and 101 rows (--rows) needs"),
    ("size: dem sample disks 1e9", ["dem", "sample", "--disks", "1000000000", "--out", "o"], 1,
     "a test of 1,000,000,000 disks (--disks)"),
    ("size: dem sample rows 1e9", ["dem", "sample", "--dim", "3", "--rows", "1000000000", "--out", "o"], 1,
     "1,000,000,001 rows (--rows) needs"),
    # program expressions that fail at run time
    ("expression q = p0/(p0-p0)", ["run", "program", "expr_q_div0.toml", "--out", "o", *FAST], 1,
     "q = 'p0 / (p0 - p0)' is not a finite stress at p0 = 200000.0 Pa (division by zero)"),
    ("expression sig22 = p0/(p0-p0)", ["run", "program", "expr_sig22_div0.toml", "--out", "o", *FAST], 1,
     "sig22 = 'p0 / (p0 - p0)' is not a finite stress at p0 = 200000.0 Pa (division by zero)"),
    ("expression 1e308 * 1e308", ["run", "program", "expr_until_overflow.toml", "--out", "o", *FAST], 1,
     "1e+308 * 1e+308 is not a finite number (overflow)"),
    ("expression q = p0/(p0-p0), 3D", ["run", "program", "expr_q_div0_3d.toml", "--out", "o"], 1,
     "q = 'p0 / (p0 - p0)' is not a finite stress at p0 = 200000.0 Pa (division by zero)"),
    ("expression sig22 = p0/(p0-p0), 3D", ["run", "program", "expr_sig22_div0_3d.toml", "--out", "o"], 1,
     "sig22 = 'p0 / (p0 - p0)' is not a finite stress"),
    ("expression 1e308 * 1e308, 3D", ["run", "program", "expr_until_overflow_3d.toml", "--out", "o"], 1,
     "(overflow)"),
    ("expression q = p0/(p0-p0), stability", ["stability", "--program", "expr_q_div0.toml", "--out", "o", *FAST],
     1, "(division by zero)"),
    ("expression sig22 = p0/(p0-p0), stability", ["stability", "--program", "expr_sig22_div0.toml", "--out", "o",
                                                  *FAST], 1, "(division by zero)"),
    ("expression q = p0/(p0-p0), stability 3D", ["stability", "--program", "expr_q_div0_3d.toml", "--out", "o"],
     1, "(division by zero)"),
    ("expression sig22 = p0/(p0-p0), stability 3D", ["stability", "--program", "expr_sig22_div0_3d.toml",
                                                     "--out", "o"], 1, "(division by zero)"),
    ("expression abs uncalled", ["run", "program", "expr_abs.toml", "--out", "o", *FAST], 1,
     "abs is a function: abs(x)"),
    # outputs, files and options
    ("out a dangling link, triaxial", ["run", "triaxial", "--order", "9", "--azimuths", "2", "--axial-strain",
                                       "0.01", "--out", "dangling"], 1, "'dangling' is a dangling symbolic link"),
    ("out a looping link, triaxial", ["run", "triaxial", "--out", "loop"], 1, "'loop' is a looping symbolic link"),
    ("out under a dangling link", ["run", "iso", *FAST, "--out", "dangling/x"], 1, "'dangling' is a dangling"),
    ("out a dangling link, fem", ["fem", "biaxial", "--out", "dangling"], 1, "is a dangling symbolic link"),
    ("out a looping link, fem", ["fem", "biaxial", "--out", "loop"], 1, "is a looping symbolic link"),
    ("out a dangling link, calibrate", [*CAL, "--out", "dangling"], 1, "is a dangling symbolic link"),
    ("out a looping link, calibrate", [*CAL, "--out", "loop"], 1, "is a looping symbolic link"),
    ("out a dangling link, model file", ["surrogate", "trust", MODEL, "nowhere", "--out", "dangling"], 1,
     "is a dangling symbolic link"),
    ("BOM strain path", ["run", "strain-path", "bom_strain.csv", "--out", "o"], 1, "line 2: 'abc' is not a number"),
    ("BOM calibration data", ["calibrate", "--data", "drained:200kPa:bom_test.csv", "--out", "o"], 1,
     "line 2: column q must be a number"),
    ("strain path a folder", ["run", "strain-path", "folder.safetensors", "--out", "o"], 1, "is a folder"),
    ("strain path /dev/zero", ["run", "strain-path", "/dev/zero", "--out", "o"], 1, "longer than 1,048,576"),
    ("solver surrogate:", ["run", "iso", *FAST, "--solver", "surrogate:", "--out", "o"], 1,
     "'surrogate:' names nothing after a colon"),
    ("solver surrogate:+", ["run", "iso", *FAST, "--solver", "surrogate:+", "--out", "o"], 1,
     "a model reference is empty"),
    ("solver dem:", ["run", "iso", *FAST, "--solver", "dem:", "--out", "o"], 1, "names nothing after a colon"),
    ("solver surrogate:, calibrate", [*CAL, "--solver", "surrogate:", "--out", "o"], 1,
     "names nothing after a colon"),
    ("evaluate an empty model", ["surrogate", "evaluate", "", "--data", "nowhere", "--out", "o"], 1,
     "a model reference is empty"),
    ("model file a folder", ["run", "iso", *FAST, "--solver", "surrogate:folder.safetensors", "--out", "o"], 1,
     "model file 'folder.safetensors' is a folder"),
    ("model file /dev/zero", ["run", "iso", *FAST, "--solver", "surrogate:/dev/zero", "--out", "o"], 1,
     "model file '/dev/zero' is not a regular file"),
    ("evaluate model /dev/zero", ["surrogate", "evaluate", "/dev/zero", "--data", "nowhere", "--out", "o"], 1,
     "is not a regular file"),
    ("workers 0, calibrate", [*CAL, "--workers", "0", "--out", "o"], 2, "'--workers'"),
    ("workers -1, data generate", ["data", "generate", "2", "--workers", "-1", "--out", "o"], 2, "'--workers'"),
    ("undrained extension, dem sample", ["dem", "sample", "--dim", "3", "--undrained", "--extension", "--out", "o"],
     1, "drained and undrained compression and drained extension"),
    # calibration
    ("calibrate 3D family bounds outside its domain", ["calibrate", "--data", "triaxial-drained:200kPa:t3.csv",
                                                       "--solver", "surrogate:family", "--fit", "phi_g",
                                                       "--bounds", "phi_g=5:60", "--out", "o"], 1,
     "--bounds phi_g=5:60 reaches outside the model's training domain (10–45°)"),
    ("calibrate strains in percent under 1", ["calibrate", "--data", "drained:200kPa:percent_small.csv",
                                              "--out", "o"], 1, "eps11 reaches 0.96, half the specimen's height"
                                                                " or more: that looks like a percentage"),
    ("calibrate q in kPa", ["calibrate", "--data", "drained:200kPa:q_kpa.csv", "--out", "o"], 1,
     "q_kpa: q peaks at 380 Pa, 0.0019 of p0 = 200 kPa: that looks like kPa"),
    ("calibrate p0 without unit", ["calibrate", "--data", "triaxial-drained:100:t3.csv", "--out", "o"], 1,
     "p0 100 has no unit and would be 100 Pa: give its unit (100kPa"),
    # fem and failure surface
    ("failure surface step 1e-9", ["failure-surface", "--step", "1e-9", "--max-strain", "0.9", "--out", "o"], 1,
     "increments of each ray (max_strain 0.9 in steps of 1e-09): 9e+08 exceeds the limit"),
    ("failure surface 5000 Lode angles", ["failure-surface", "--lode", ",".join(f"{60 * i / 5000:.4f}" for i in
                                          range(1, 5001)), "--out", "o"], 1, "5001 Lode angles (with 0): at most 61"),
    ("failure surface rays times increments", ["failure-surface", "--lode", ",".join(str(i) for i in range(61)),
                                           "--step", "1e-6", "--out", "o"], 1,
     "increments of the failure surface (61 rays × 300000): 1.83e+07 exceeds the limit"),
    ("fem nonlocal ell 1e9", ["fem", "biaxial", "--regularization", "nonlocal:ell=1e9", "--out", "o"], 1,
     "ell = 1e+09 m exceeds the largest dimension of the 0.05 x 0.1 m domain"),
    ("fem footing ell above the layer", ["fem", "footing", "--regularization", "nonlocal:ell=2", "--out", "o"], 1,
     "exceeds the largest dimension of the 1 x 0.5 m domain (1 m)"),
    # pressures without unit, and the 3D model's cell and parameters (one rule each)
    ("p0 without unit, run iso", ["run", "iso", "--p0", "100", "--out", "o"], 1,
     "--p0 100 has no unit and would be 100 Pa: give its unit (100kPa, or 100Pa if Pa is meant)"),
    ("p0 without unit in a list, run triaxial", ["run", "triaxial", "--p0", "100kPa,50", "--out", "o"], 1,
     "--p0 50 has no unit and would be 50 Pa"),
    ("p without unit, failure-surface", ["failure-surface", "--p", "200", "--out", "o"], 1,
     "--p 200 has no unit and would be 200 Pa"),
    ("p0 without unit, stability", ["stability", "--p0", "100", "--out", "o"], 1, "--p0 100 has no unit"),
    ("p0 without unit, stability triaxial", ["stability", "--test", "triaxial", "--p0", "100", "--out", "o"], 1,
     "--p0 100 has no unit"),
    ("p0 without unit, fem footing", ["fem", "footing", "--p0", "100", "--out", "o"], 1, "--p0 100 has no unit"),
    ("p0 without unit, dem sample", ["dem", "sample", "--p0", "100", "--out", "o"], 1, "--p0 100 has no unit"),
    ("p0 without unit, data lab", ["data", "lab", "t3.csv", "--kind", "triaxial-drained", "--p0", "100",
                                   "--out", "o"], 1, "--p0 100 has no unit"),
    ("3D calibrate given alpha_omega", ["calibrate", "--data", "triaxial-drained:200kPa:t3.csv", "-p",
                                        "alpha_omega=0.3", "--out", "o"], 1, "--fabric A on the command line"),
    ("3D program with a DEM hexagon", ["run", "program", "iso_3d.toml", "--solver", "dem:standard", "--out", "o"], 1,
     "is a DEM cell solver (YADE): the 3D model's DEM cell is the bi-hexagon of spheres, dem:bihexagon"),
    ("3D program gated", ["run", "program", "iso_3d.toml", "--solver", "surrogate", "--gate", "0.99", "--out", "o"],
     1, "--gate and --fallback gate a 2D learned cell: a 3D program's learned bi-hexagon runs ungated"),
    # the cells of a database: --solver resolved by the solver registry, decided by its declarations
    ("data generate, learned cells", ["data", "generate", "2", "--solver", "surrogate", "--out", "o"], 1,
     "--solver must be an exact cell solver (closed-form or dem), got the learned 'surrogate'"),
    ("data generate, unknown solver", ["data", "generate", "2", "--solver", "foo", "--out", "o"], 1,
     "unknown cell solver 'foo'"),
    ("data generate, mesostructure of the closed form", ["data", "generate", "2", "--mesostructure",
                                                         "hexagon-center", "--out", "o"], 1,
     "--mesostructure needs --solver dem"),
    ("data generate, mesostructure twice", ["data", "generate", "2", "--solver", "dem:standard",
                                            "--mesostructure", "hexagon-center", "--out", "o"], 1,
     "--mesostructure needs --solver dem"),
    ("data generate, DEM cells in 3D", ["data", "generate", "2", "--dim", "3", "--solver", "dem", "--out", "o"], 1,
     "--dim 3 rows are the closed-form bi-hexagon's; --solver dem:standard is a 2D cell solver option only"),
    # hertz-mindlin
    ("hertz-mindlin with learned cells", ["run", "biaxial", "--solver", "surrogate", "-p", "contact=hertz-mindlin",
                                          "--out", "o"], 1,
     "contact=hertz-mindlin is not implemented by the surrogate cells"),
    ("rebirth with learned 3D cells", ["run", "triaxial", "--solver", "surrogate", "-p", "renewal=rebirth",
                                       "--out", "o"], 1, "renewal=rebirth is not implemented by the surrogate cells"),
    # renewal=mix: the hexagon volume only
    ("mix with the box volume", ["run", "biaxial", "-p", "renewal=mix", "-p", "volume=box", "--out", "o"], 1,
     "renewal=mix is derived for volume=hexagon"),
    ("mix with learned cells", ["run", "biaxial", "--solver", "surrogate", "-p", "renewal=mix", "--out", "o"], 1,
     "renewal=mix is not implemented by the surrogate cells"),
    ("hertz-mindlin rows of DEM cells", ["data", "generate", "1", "--solver", "dem", "-p", "contact=hertz-mindlin",
                                         "--out", "o"], 1, "contact=hertz-mindlin is not implemented by the dem:standard cells"),
]


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _prepare(folder: Path) -> None:
    for name, content in FILES.items():
        (folder / name).write_bytes(content if isinstance(content, bytes) else content.encode())
    (folder / "folder.safetensors").mkdir()
    (folder / "dangling").symlink_to("nowhere")
    (folder / "loop").symlink_to("loop")


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


def test_rev3d_guard_counts_its_geometry_before_building_it(monkeypatch):
    """A 3D REV's estimate is its geometry (cells × GEOMETRY_BYTES_PER_CELL) and its sets' cells
    (× the solver's bytes per cell), checked before the frames are built: at the budget it is
    built, a byte less is refused and no frame is made."""
    from hmodel.cell.bihex import BiHexSolver
    from hmodel.rev import Rev3D, Sphere
    from hmodel.rev.rev3d import GEOMETRY_BYTES_PER_CELL

    sphere = Sphere(order=9, n_azimuth=2)  # 38 bi-hexagons
    budget = 38 * (GEOMETRY_BYTES_PER_CELL + BiHexSolver().bytes_per_cell)
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(budget))
    Rev3D(Params(), sphere)
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(budget - 1))
    monkeypatch.setattr(Sphere, "frames", lambda self: pytest.fail("frames built before the guard"))
    with pytest.raises(WorkTooLarge, match="1 material point × 38 bi-hexagons"):
        Rev3D(Params(), sphere)


@pytest.mark.parametrize("test", ["biaxial", "triaxial"])
def test_rows_guard_counts_the_table_before_the_run(monkeypatch, test):
    """A test's table has points × (increments + 1) rows known before it runs (its consolidation
    counts its final row; its increments are counted as they are recorded): at the limit the run
    starts and the recorder refuses the consolidation's rows past it, one row less is refused
    before anything is built. Their memory (rows × columns × TABLE_BYTES_PER_VALUE) counts with
    the cells': at that budget the test runs, a byte less is refused."""
    from hmodel.cell.bihex import BiHexSolver
    from hmodel.limits import TABLE_BYTES_PER_VALUE
    from hmodel.loading import run_biaxial, run_triaxial
    from hmodel.loading.result import columns_for
    from hmodel.rev import Sphere

    if test == "biaxial":
        params, cells, columns = Params(n_theta=12), 12 * ClosedFormSolver.bytes_per_cell, columns_for(3)
        run = lambda: run_biaxial(params, [1e5, 2e5, 3e5], 0.001)  # noqa: E731
    else:
        sphere = Sphere(order=3, n_azimuth=1)  # 3 bi-hexagons
        params, cells, columns = Params(sliding_rhs="equilibrium"), 3 * BiHexSolver().bytes_per_cell, columns_for(6)
        run = lambda: run_triaxial(params, [1e5, 2e5, 3e5], 0.001, sphere=sphere)  # noqa: E731
    rows = 3 * (10 + 1)  # 0.001 in increments of 1e-4
    monkeypatch.setenv("HMODEL_MAX_ROWS", str(rows))
    with pytest.raises(WorkTooLarge, match="the rows recorded so far"):
        run()
    monkeypatch.setenv("HMODEL_MAX_ROWS", str(rows - 1))
    with pytest.raises(WorkTooLarge, match=f"3 material points × 11 rows: a result table of {rows} rows exceeds"):
        run()
    monkeypatch.delenv("HMODEL_MAX_ROWS")
    budget = 3 * cells + rows * len(columns) * TABLE_BYTES_PER_VALUE
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(budget))
    assert len(run()) > rows
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(budget - 1))
    with pytest.raises(WorkTooLarge, match=f"3 material points .* and a result table of {rows} rows needs"):
        run()


def test_rows_guard_counts_a_programs_increments(monkeypatch):
    from hmodel.loading import Program

    table = {"stage": [{"preset": "iso", "p": "200kPa"}, {"preset": "drained", "eps11": 0.01, "steps": 50},
                       {"repeat": 3, "stages": [{"preset": "drained", "eps11": -0.001, "steps": 10}]}]}
    monkeypatch.setenv("HMODEL_MAX_ROWS", str(1 + 50 + 30))
    assert Program.from_dict(table).n_increments == 81
    monkeypatch.setenv("HMODEL_MAX_ROWS", str(80))
    with pytest.raises(WorkTooLarge, match="a result table of 81 rows exceeds the limit of 80 rows"):
        Program.from_dict(table)


def test_memory_guard_default_follows_the_address_space_limit(monkeypatch):
    """Under ``ulimit -v`` an allocation fails however much memory is free: the default budget is
    then half the address space left, when that is less than the available memory."""
    import resource

    import hmodel.limits as limits

    monkeypatch.setattr(limits, "available_memory", lambda: 2**50)
    real = resource.getrlimit
    vm = int(next(line for line in open("/proc/self/status") if line.startswith("VmSize:")).split()[1]) * 1024
    monkeypatch.setattr(resource, "getrlimit", lambda which: (vm + 2**30, resource.RLIM_INFINITY)
                        if which == resource.RLIMIT_AS else real(which))
    limit, source = limits.memory_limit(env={})
    assert 0 < limit <= 2**29 and "address space left under ulimit -v" in source
    with pytest.raises(WorkTooLarge, match="address space"):
        check_memory(2**29 + 1, "a request", env={})


@pytest.mark.parametrize("cause", [MemoryError(), SystemError("returned a result with an exception set")])
def test_out_of_memory_inside_a_compiled_kernel_is_one_line(tmp_path, monkeypatch, capsys, cause):
    """An allocation that fails inside a Numba kernel reaches Python as a SystemError caused by a
    MemoryError (or as the MemoryError itself): one line; another SystemError is a bug."""
    import hmodel.loading.compiled as compiled

    def kernel(*args):
        if isinstance(cause, MemoryError):
            raise MemoryError("Allocation failed (probably too large).")
        raise SystemError("CPUDispatcher(<function _iso_steps>) returned a result with an exception set") \
            from MemoryError("Allocation failed (probably too large).")

    monkeypatch.setattr(compiled, "_run_steps", kernel)
    code, err, added = run_case([*T3, "--order", "3", "--azimuths", "1", "--out", "o"], tmp_path, capsys)
    assert code == 1 and err.startswith("hmodel: error: out of memory") and err.count("\n") == 1, err
    assert not added

    def bug(*args):
        raise SystemError("a bug")

    monkeypatch.setattr(compiled, "_run_steps", bug)
    with pytest.raises(SystemError, match="a bug"):
        main([*T3, "--order", "3", "--azimuths", "1", "--out", str(tmp_path / "never")])


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


# ---------------------------------------------------------------- expressions not a number at run time

_SMALL_3D = "dim = 3\n[sphere]\norder = 9\nazimuths = 2\n"


@pytest.mark.parametrize("until", ["q >= p0 / (p0 - p0)", "q >= (p0 - p0) / (p0 - p0)"])
@pytest.mark.parametrize("head, fast", [("", FAST), (_SMALL_3D, [])], ids=["2D", "3D"])
def test_a_criterion_that_is_not_a_number_is_not_met(tmp_path, capsys, head, fast, until):
    """``until = "q >= p0 / (p0 - p0)"`` used to be a ZeroDivisionError traceback: the criterion
    is never met, so the stage runs through and the result is the one without it."""
    stage = DRAINED + "eps11 = 0.002\nsteps = 5\n"
    (tmp_path / "plain.toml").write_text(head + stage)
    (tmp_path / "until.toml").write_text(head + stage + f'until = "{until}"\n')
    for name in ("plain", "until"):
        code, err, _ = run_case(["run", "program", f"{name}.toml", "--out", name, *fast], tmp_path, capsys)
        assert code == 0, err
    assert (tmp_path / "until" / "result.csv").read_bytes() == (tmp_path / "plain" / "result.csv").read_bytes()
    code, err, added = run_case(["stability", "--program", "until.toml", "--out", "s", *fast], tmp_path, capsys)
    assert code == 0 and "s/summary.csv" in added, err


# ---------------------------------------------------------------- random 3D programs (Hypothesis)

# mostly values that run, so that the runs are reached; now and then anything
_often = st.integers(0, 3)
_strain3 = _often.flatmap(lambda k: st.sampled_from([0, 0.0, 0.001, -0.001, 0.005]) if k else
                          st.floats(allow_nan=True, allow_infinity=True))
_stress3 = _often.flatmap(lambda k: st.sampled_from(["hold", "p0", "0.5 * p0", "200kPa", 150000.0, "1.2 * p0"]) if k
                          else st.one_of(st.sampled_from(["p0 / (p0 - p0)", "(p0 - p0) / (p0 - p0)",
                                                          "p0 * 1e308 * 10", True]), _expression))
_shear3 = {c: st.one_of(st.just((f"eps{c}", 0)), st.tuples(st.just(f"eps{c}"), _strain3),
                        st.tuples(st.just(f"sig{c}"), _stress3)) for c in ("23", "13", "12")}
_normal3 = {c: st.one_of(st.tuples(st.just(f"eps{c}"), _strain3), st.tuples(st.just(f"sig{c}"), _stress3))
            for c in ("11", "22", "33")}
# a row of a combination in place of a normal component's, or a seventh row
_combination3 = st.tuples(st.sampled_from(["p", "q", "eps_v", "b", "sig22-sig33", "eps22-eps33", "eps12", "bogus"]),
                          st.one_of(_stress3, _strain3, st.sampled_from([0.5, 1.5, -1])))


def _control_table(rows, combination, slot) -> dict:
    rows = list(rows)
    if combination is not None:
        if slot is None:
            rows.append(combination)
        else:
            rows[slot] = combination
    return dict(rows)


_control3 = st.tuples(st.tuples(*_normal3.values(), *_shear3.values()), st.none() | _combination3,
                      st.sampled_from([None, 1, 2])).map(lambda t: _control_table(*t))
_criterion3 = st.tuples(st.sampled_from(["q", "p", "eps33", "sig33", "q_eq", "lode", "b", "eps23", "p0", "theta"]),
                        st.sampled_from([">=", "<", "<="]), _expression).map(" ".join)
_options3 = {"steps": st.sampled_from([1, 3, 10, 0, 10**25]), "until": _criterion3,
             "max_increment": st.floats(allow_nan=True, allow_infinity=True), "name": st.text(max_size=8),
             "stop_on_failure": st.booleans()}
_stage3 = st.one_of(
    st.fixed_dictionaries({"control": _control3}, optional=_options3),
    st.fixed_dictionaries({"control": _control3, "steps": st.sampled_from([1, 3, 10])}),
    st.fixed_dictionaries({"preset": st.sampled_from(["drained", "undrained", "oedometric", "constant_p",
                                                      "true_triaxial", "proportional", "iso", "spin"])},
                          optional={"eps11": _strain3, "q": _stress3, "b": st.sampled_from([0.0, 0.5, 1.5]),
                                    "direction": st.lists(_strain3, max_size=6), "magnitude": _strain3, **_options3}),
    _stage)
_sphere3 = st.fixed_dictionaries({"order": st.sampled_from([9] * 6 + [3, 13])},
                                 optional={"azimuths": st.sampled_from([2, 2, 2, 1, 0]),
                                           "alpha_omega": st.sampled_from([0.0, 0.3, -0.5, 1.5])})


def _toml_inline(v) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_value(str(k))} = {_toml_inline(x)}" for k, x in v.items()) + "}"
    return _toml_value(v)


@settings(_RANDOM, max_examples=25)
@given(sphere=_sphere3, stages=st.lists(_stage3, min_size=0, max_size=3), dim=st.sampled_from([3] * 7 + [2]))
@pytest.mark.slow
def test_random_3d_programs(tmp_path_factory, capsys, bounded, sphere, stages, dim):
    folder = tmp_path_factory.mktemp("toml3d")
    text = f"dim = {dim}\n[sphere]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in sphere.items())
    for s in [{"preset": "iso", "p": "200kPa"}] + stages:
        text += "[[stage]]\n" + "".join(f"{k} = {_toml_inline(v)}\n" for k, v in s.items())
    (folder / "p.toml").write_text(text)
    _contract(*run_case(["run", "program", "p.toml", "--out", "o"], folder, capsys))
