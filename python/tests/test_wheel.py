"""`python -m build` makes an sdist that carries the C library and a wheel built from that sdist
alone (unpacked outside the clone, where the repository is out of reach); the wheel installs
into a clean virtual environment, where bpx imports from site-packages with its stubs and
works."""

import os
import subprocess
import sys
import tarfile
import textwrap

import pytest

PYTHON_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(*cmd, **kwargs):
    result = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f"{' '.join(cmd)}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result.stdout


@pytest.mark.skipif(os.environ.get("BPX_SKIP_WHEEL_TEST") == "1", reason="BPX_SKIP_WHEEL_TEST=1")
def test_sdist_and_wheel_build_and_install_in_a_clean_venv(tmp_path):
    pytest.importorskip("build", reason="needs the build package (python/ci.sh installs it)")
    try:
        import scikit_build_core  # noqa: F401

        isolation = ["--no-isolation"]  # the build backend is here already: no download
    except ImportError:
        isolation = []
    env = dict(os.environ, CMAKE_BUILD_PARALLEL_LEVEL="2")
    dist = tmp_path / "dist"
    # The sdist first, then the wheel from the sdist unpacked in a temporary folder: the
    # wheel's build sees nothing of the clone.
    run(sys.executable, "-m", "build", *isolation, "--outdir", str(dist), PYTHON_DIR,
        env=env, cwd=str(tmp_path))
    sdists = list(dist.glob("bpx-*.tar.gz"))
    wheels = list(dist.glob("bpx-*.whl"))
    assert len(sdists) == 1 and len(wheels) == 1
    with tarfile.open(sdists[0]) as tar:
        members = {m.name.split("/", 1)[1]: m for m in tar.getmembers() if "/" in m.name}
    links = [name for name, m in members.items() if m.issym() or m.islnk()]
    assert links == [], f"the sdist holds links, which dangle once unpacked: {links}"
    for needed in ("LICENSE", "CMakeLists.txt", "csrc/_bpx.c", "libbpx/CMakeLists.txt",
                   "libbpx/LICENSE", "libbpx/include/bpx/bpx.h", "libbpx/include/bpx/query.h",
                   "libbpx/src/core/world.c", "libbpx/src/query/query.c",
                   "libbpx/cmake/bpxConfig.cmake.in", "libbpx/rtl/bpx_board.sv"):
        assert needed in members and members[needed].isfile(), f"{needed} is not in the sdist"
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
        with bpx.World() as world:
            world.set_boxes(boxes)
            assert world.collide().tolist() == [[0, 1]]
            assert world.query_box([0, 0, 0, 0.5, 0.5, 0.5]).tolist() == [0]
        assert any(f.name == "LICENSE" for f in md.files("bpx")), "no LICENSE in the wheel"
        print("ok", bpx.__version__)
        """
    )
    out = run(python, "-c", check, cwd=str(tmp_path))  # not from the source tree
    assert out.startswith("ok")
