"""Device arrays without a GPU: the same views (shapes, strides, dtypes, DLPack capsules) over a
host buffer laid out like the CUDA backend's state, read by NumPy through DLPack."""

import gc
import sys

import numpy as np
import pytest

from rtmpm import _rtmpm

NFIELDS, F_X, F_C, F_F, F_MAT, F_ID = 29, 0, 6, 15, 27, 28


def state(n, stride, dtype):
    """Field f of slot i holds 1000 f + i (ids and materials: integer bits, like the GPU)."""
    s = np.zeros(NFIELDS * stride, dtype)
    for f in range(NFIELDS):
        s[f * stride : f * stride + n] = 1000 * f + np.arange(n)
    for f in (F_MAT, F_ID):
        bits = s.view(np.uint32 if dtype == np.float32 else np.uint64)
        bits[f * stride : f * stride + n] = 7 * np.arange(n) + f
    return s


@pytest.mark.skipif(not hasattr(np, "from_dlpack"), reason="NumPy without from_dlpack")
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_views_have_the_documented_layout(dtype):
    n, stride = 5, 8
    s = state(n, stride, dtype)
    x = _rtmpm._layout_view(s, n, stride, F_X, [3])
    assert x.shape == [n, 3] and x.dtype == np.dtype(dtype).name
    assert x.strides == [s.itemsize, stride * s.itemsize]
    assert x.__dlpack_device__() == (1, 0)
    a = np.from_dlpack(x)
    assert a.shape == (n, 3)
    for i in range(n):
        for k in range(3):
            assert a[i, k] == 1000 * (F_X + k) + i
    F = np.from_dlpack(_rtmpm._layout_view(s, n, stride, F_F, [3, 3]))
    for i in range(n):
        for r in range(3):
            for c in range(3):
                assert F[i, r, c] == 1000 * (F_F + 3 * c + r) + i  # column-major components
    ids = np.from_dlpack(_rtmpm._layout_view(s, n, stride, F_ID, [], int32=True))
    assert ids.dtype == np.int32 and list(ids) == [7 * i + F_ID for i in range(n)]
    cai = x.__cuda_array_interface__
    assert cai["shape"] == (n, 3) and cai["version"] == 3
    assert cai["typestr"] == ("<f4" if dtype == np.float32 else "<f8")
    assert cai["data"] == (x.ptr, False) and cai["strides"] == (s.itemsize, stride * s.itemsize)


@pytest.mark.skipif(not hasattr(np, "from_dlpack"), reason="NumPy without from_dlpack")
def test_a_consumed_view_keeps_its_owner_alive_and_releases_it():
    n, stride = 4, 4
    s = state(n, stride, np.float32)
    base = sys.getrefcount(s)
    a = np.from_dlpack(_rtmpm._layout_view(s, n, stride, F_X, [3]))
    gc.collect()
    assert sys.getrefcount(s) > base  # the consumer's array holds the view's owner
    del a
    gc.collect()
    assert sys.getrefcount(s) == base
    # A capsule that is never consumed frees its tensor too.
    cap = _rtmpm._layout_view(s, n, stride, F_X, [3]).__dlpack__()
    assert sys.getrefcount(s) > base
    del cap
    gc.collect()
    assert sys.getrefcount(s) == base


def test_copy_and_other_devices_are_refused():
    s = state(2, 2, np.float32)
    v = _rtmpm._layout_view(s, 2, 2, F_X, [3])
    with pytest.raises(BufferError):
        v.__dlpack__(copy=True)
    with pytest.raises(BufferError):
        v.__dlpack__(dl_device=(2, 0))
