"""The compiled kernels' cache directory (hmodel.kernel_cache): one per version of the sources,
because Numba's own cache does not see a change in an inlined function of another module."""

import os
import subprocess
import sys
import textwrap

from hmodel import kernel_cache

RUN = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    if sys.argv[2] == "configure":  # the module alone: importing hmodel would configure for hmodel
        import importlib.util
        from pathlib import Path
        spec = importlib.util.spec_from_file_location("kernel_cache", sys.argv[3])
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.configure(Path(sys.argv[1]))
    import kernel_a
    print(kernel_a.g())
""")


def _package(root, value):
    (root / "kernel_b.py").write_text(f"from numba import njit\n\n\n@njit(inline='always')\ndef f():\n"
                                      f"    return {value}\n")
    os.utime(root / "kernel_b.py", (1e9 + value, 1e9 + value))  # a new mtime whatever the clock
    (root / "kernel_a.py").write_text("from numba import njit\nfrom kernel_b import f\n\n\n"
                                      "@njit(cache=True)\ndef g():\n    return f()\n")


def _run(root, mode, env):
    out = subprocess.run([sys.executable, "-c", RUN, str(root), mode, kernel_cache.__file__], env=env, capture_output=True,
                         text=True, check=True, timeout=300)
    return int(out.stdout.split()[-1])


def test_a_changed_inlined_function_is_recompiled_only_with_a_directory_per_source(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "HMODEL_CACHE_DIR")}
    fixed = {**env, "NUMBA_CACHE_DIR": str(tmp_path / "fixed")}
    keyed = {**env, "HMODEL_CACHE_DIR": str(tmp_path / "keyed")}
    _package(src, 1)
    assert _run(src, "plain", fixed) == 1 and _run(src, "configure", keyed) == 1
    _package(src, 2)
    # Numba's cache alone keeps the kernel that inlined the old function: the case guarded against
    assert _run(src, "plain", fixed) == 1
    assert _run(src, "configure", keyed) == 2
    assert len(list((tmp_path / "keyed").iterdir())) == 2  # one directory per version


def test_the_digest_follows_every_source_file(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.py").write_text("y = 1\n")
    first = kernel_cache.source_digest(tmp_path)
    assert kernel_cache.source_digest(tmp_path) == first
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    assert kernel_cache.source_digest(tmp_path) != first
    (tmp_path / "sub" / "b.py").write_text("y = 1\n")
    assert kernel_cache.source_digest(tmp_path) == first
    (tmp_path / "notes.txt").write_text("not a source")
    assert kernel_cache.source_digest(tmp_path) == first


def test_a_users_numba_cache_dir_is_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("HMODEL_CACHE_DIR", str(tmp_path / "ours"))
    assert kernel_cache.configure(tmp_path) is None
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine") and not (tmp_path / "ours").exists()


def test_the_package_is_configured_on_import():
    # this process imported hmodel: its kernels cache under a directory named by the digest,
    # unless the environment named one
    assert os.environ["NUMBA_CACHE_DIR"]
    out = subprocess.run([sys.executable, "-c", "import os, hmodel; print(os.environ['NUMBA_CACHE_DIR'])"],
                         env={k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"},
                         capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip().endswith(f"numba-{kernel_cache.source_digest()}")
