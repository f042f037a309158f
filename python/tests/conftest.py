import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # scenes.py

import bpx  # noqa: E402

# Backends that run on this machine, auto first; model (the FPGA clock by clock), rtl (the chip's
# RTL simulated, built only with -C cmake.define.BPX_RTL_BACKEND=ON), opencl (PoCL on a CPU) and
# hybrid (opencl beside the CPU here) are slow per box, so their tests use smaller sets.
BACKENDS = bpx.available_backends()
SLOW_BACKENDS = {"model", "rtl", "opencl", "cuda", "hybrid", "reference"}


def pytest_report_header(config):
    rows = [f"{b.name}{'' if b.available else ' (unavailable: ' + b.reason + ')'}"
            for b in bpx.backends()]
    return [f"bpx {bpx.__version__} from {os.path.dirname(bpx.__file__)}",
            "backends: " + ", ".join(rows)]


@pytest.fixture(params=BACKENDS)
def backend(request):
    return request.param
