"""The numerics the recorded results were made with, the same on every x86-64 host with AVX2.

Why: an optimisation's path is chaotic in round-off. numpy picks its SIMD kernels at import by
the CPU (on AVX-512 hosts its float64 ``sin``/``cos``/``exp`` come from other kernels, a few ULP
apart), and OpenBLAS picks its ``dgemm``/``dgemv`` kernels by the CPU too (summing in another
order). Both are correct, but the hybrid optimiser's trust-region path through a design space
parts at such differences, so `flexopt run constant-force` finds another design on an AVX-512
host than on an AVX2 one (measured, session 33 on an AMD EPYC with AVX-512: RMS 0.002935 N,
280 designs, against the recorded 0.00268 N; both MET 5/5). The goldens (tests/golden) and each
example's recorded design hold every digit of one run, so they are recorded, and tested, with
numpy's AVX-512 kernels switched off and OpenBLAS's Haswell kernels, which is what an AVX2
host (Intel Haswell and later, AMD Zen) uses anyway: there these settings change nothing.

``tests/conftest.py`` sets :data:`ENV` before anything imports numpy, so the README's test
command, CI and every subprocess a test starts (they inherit the environment) run on these
numerics. To record a golden or an example's design the same way::

    python tests/reference_numerics.py flexopt run constant-force
    python tests/reference_numerics.py python tests/golden/make_golden.py runs/<folder>

A user's own runs keep numpy's and OpenBLAS's choices (the fastest kernels for their CPU): on
an AVX-512 host they may find a design other than the recorded one, of the same quality
(README, "Quick start"). Only x86-64 hosts are covered (on ARM these variables do nothing: the
goldens are not expected to hold to every digit there).
"""

from __future__ import annotations

import os
import sys

#: numpy >= 2.4 names its x86 dispatch targets X86_V2/V3/V4 (and AVX512_ICL, AVX512_SPR on top);
#: switching off a name the host lacks, or one an older numpy does not know, is ignored.
#: OPENBLAS_CORETYPE chooses OpenBLAS's kernels (numpy's and scipy's wheels are DYNAMIC_ARCH).
ENV = {
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OPENBLAS_CORETYPE": "Haswell",
}


def apply(environ: dict[str, str] | None = None) -> list[str]:
    """Set :data:`ENV` in ``environ`` (default ``os.environ``) unless already set there; returns
    the names it set. Effective only before numpy (and scipy's OpenBLAS) is first imported."""
    environ = os.environ if environ is None else environ
    done = []
    for key, value in ENV.items():
        if key not in environ:
            environ[key] = value
            done.append(key)
    return done


if __name__ == "__main__":  # python tests/reference_numerics.py COMMAND [ARGS...]
    if len(sys.argv) < 2:
        sys.exit("usage: python tests/reference_numerics.py COMMAND [ARGS...]")
    apply()
    os.execvp(sys.argv[1], sys.argv[1:])
