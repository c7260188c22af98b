"""vision._blas: one OpenBLAS thread for a block, the previous count restored."""

import numpy as np
import pytest

from vision._blas import _openblas, one_blas_thread


def test_one_blas_thread_holds_one_thread_and_restores_the_count():
    lib = _openblas()
    if lib is None:
        pytest.skip("numpy's BLAS is not a bundled OpenBLAS")
    get, put = lib
    before = int(get())
    with one_blas_thread():
        assert int(get()) == 1
        a = np.random.default_rng(0).normal(size=(200, 3))
        np.testing.assert_allclose(a @ np.eye(3), a)
    assert int(get()) == before
