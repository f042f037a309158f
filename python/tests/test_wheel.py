"""The wheel builds from the clone and installs into a clean virtual environment, where bpx
imports from site-packages with its stubs and works."""

import os
import subprocess
import sys
import textwrap

import pytest

PYTHON_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*cmd, **kwargs):
    result = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f"{' '.join(cmd)}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result.stdout


@pytest.mark.skipif(os.environ.get("BPX_SKIP_WHEEL_TEST") == "1", reason="BPX_SKIP_WHEEL_TEST=1")
def test_wheel_builds_and_installs_in_a_clean_venv(tmp_path):
    try:
        import scikit_build_core  # noqa: F401

        isolation = ["--no-build-isolation"]  # the build backend is here already: no download
    except ImportError:
        isolation = []
    env = dict(os.environ, CMAKE_BUILD_PARALLEL_LEVEL="2")
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-w", str(tmp_path / "dist"),
        PYTHON_DIR, env=env)
    wheels = list((tmp_path / "dist").glob("bpx-*.whl"))
    assert len(wheels) == 1
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", str(venv))
    python = str(venv / "bin" / "python")
    run(python, "-m", "pip", "install", "-q", str(wheels[0]))  # and NumPy, its one dependency
    check = textwrap.dedent(
        """
        import os, sys, numpy as np, bpx
        import importlib.metadata as md
        assert os.path.realpath(bpx.__file__).startswith(os.path.realpath(sys.prefix)), bpx.__file__
        here = os.path.dirname(bpx.__file__)
        assert os.path.exists(os.path.join(here, "py.typed"))
        assert os.path.exists(os.path.join(here, "_bpx.pyi"))
        requires = md.requires("bpx") or []
        assert [r.split(">")[0].split(";")[0].strip() for r in requires if "extra" not in r] == ["numpy"], requires
        boxes = np.array([[0, 0, 0, 1, 1, 1], [1, 1, 1, 2, 2, 2]], np.float32)
        assert bpx.find_pairs(boxes).tolist() == [[0, 1]]
        print("ok", bpx.__version__)
        """
    )
    out = run(python, "-c", check, cwd=str(tmp_path))  # not from the source tree
    assert out.startswith("ok")
