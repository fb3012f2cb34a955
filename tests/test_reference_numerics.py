"""The test run uses the recorded results' numerics (tests/reference_numerics.py): numpy's
AVX-512 kernels off, OpenBLAS's Haswell kernels, set by tests/conftest.py before numpy loads."""

from __future__ import annotations

import os
import platform
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import reference_numerics  # noqa: E402

sys.path.pop(0)

X86 = platform.machine().lower() in ("x86_64", "amd64")


def test_the_environment_is_set():
    for key, value in reference_numerics.ENV.items():
        assert os.environ.get(key) == value, f"{key} is {os.environ.get(key)!r}, not {value!r}"


@pytest.mark.skipif(not X86, reason="numpy's x86 dispatch targets only exist on x86-64")
def test_numpy_loaded_without_its_avx512_kernels():
    import conftest

    assert not conftest._NUMPY_FIRST, "numpy was imported before tests/conftest.py set its flags"
    features = np._core._multiarray_umath.__cpu_features__
    if "X86_V4" not in features:  # numpy < 2.4 names its targets otherwise
        pytest.skip(f"numpy {np.__version__} has no X86_V4 dispatch target")
    assert features["X86_V3"] or not features["X86_V2"]  # AVX2 hosts keep their AVX2 kernels
    assert not features["X86_V4"] and not features["AVX512_ICL"]


def test_apply_keeps_what_the_user_set():
    env = {"OPENBLAS_CORETYPE": "Zen"}
    assert reference_numerics.apply(env) == ["NPY_DISABLE_CPU_FEATURES"]
    assert env["OPENBLAS_CORETYPE"] == "Zen"
    assert env["NPY_DISABLE_CPU_FEATURES"] == reference_numerics.ENV["NPY_DISABLE_CPU_FEATURES"]
