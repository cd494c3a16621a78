"""LAPACK's band Cholesky (``dpbtrf``/``dpbtrs``) callable from several threads at once.

SciPy's ``scipy.linalg.lapack`` wrappers hold the interpreter lock for the whole call, so the 2D
direct method's factorisations (:class:`~ginn.physics.solve.ElasticitySolver`) ran one after
another whatever the number of worker threads: sixteen ``cantilever`` shapes took 0.28 s on one
thread and on two. This module calls the same routines of the same library (SciPy's own LAPACK,
through the function pointers that ``scipy.linalg.cython_lapack`` exports) by ``ctypes``, which
releases the lock during the call: the same results bit for bit, side by side on the threads.
Where the pointers cannot be had (another SciPy build), it falls back to ``scipy.linalg.lapack``.

Public names: :func:`factor`, :func:`solve`, :func:`releases_gil`.
"""

from __future__ import annotations

import ctypes
from functools import cache

import numpy as np
from scipy.linalg import lapack

__all__ = ["factor", "solve", "releases_gil"]

_int_p = ctypes.POINTER(ctypes.c_int)
_dbl_p = ctypes.POINTER(ctypes.c_double)
_UPPER = b"U"


def _pointer(name: str, restype, argtypes):
    """The C function ``name`` of ``scipy.linalg.cython_lapack`` as a ctypes function (the lock
    released during calls), or None."""
    try:
        from scipy.linalg import cython_lapack

        capsule = cython_lapack.__pyx_capi__[name]
        get_name = ctypes.pythonapi.PyCapsule_GetName
        get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
        get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
        get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
        address = get_pointer(capsule, get_name(capsule))
    except (ImportError, AttributeError, KeyError, ValueError):
        return None
    return ctypes.CFUNCTYPE(restype, *argtypes)(address) if address else None


@cache
def _routines():
    pbtrf = _pointer("dpbtrf", None, [ctypes.c_char_p, _int_p, _int_p, _dbl_p, _int_p, _int_p])
    pbtrs = _pointer("dpbtrs", None, [ctypes.c_char_p, _int_p, _int_p, _int_p, _dbl_p, _int_p, _dbl_p, _int_p, _int_p])
    return (pbtrf, pbtrs) if pbtrf is not None and pbtrs is not None else None


def releases_gil() -> bool:
    """Whether the calls run without the interpreter lock (SciPy's LAPACK pointers were found)."""
    return _routines() is not None


def _ref(x: int) -> ctypes.c_int:
    return ctypes.c_int(int(x))


def factor(ab: np.ndarray) -> tuple[np.ndarray, int]:
    """Cholesky factor ``U`` (``A = U^T U``) of the symmetric positive definite band matrix whose
    upper band ``ab`` ``(w + 1, n)`` (Fortran order, LAPACK's ``ab[w + i - j, j] = A[i, j]``) holds,
    in place. Returns ``(ab, info)``: ``info`` 0 on success, ``k > 0`` where the leading minor of
    order ``k`` is not positive definite."""
    routines = _routines()
    if routines is None:
        cf, info = lapack.dpbtrf(ab, lower=0, overwrite_ab=1)
        return cf, int(info)
    if not (ab.flags.f_contiguous and ab.dtype == np.float64):
        raise ValueError("band.factor: a float64 array in Fortran order")
    w1, n = ab.shape
    info = ctypes.c_int(0)
    routines[0](_UPPER, _ref(n), _ref(w1 - 1), ab.ctypes.data_as(_dbl_p), _ref(w1), ctypes.byref(info))
    return ab, info.value


def solve(cf: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` ``(n, L)`` (or ``(n,)``) with ``cf`` :func:`factor`'s factor of ``A``; ``b`` is not
    changed."""
    routines = _routines()
    if routines is None:
        x, info = lapack.dpbtrs(cf, b, lower=0)
    else:
        w1, n = cf.shape
        x = np.array(b, dtype=np.float64, order="F", copy=True)
        nrhs = 1 if x.ndim == 1 else x.shape[1]
        info = ctypes.c_int(0)
        routines[1](_UPPER, _ref(n), _ref(w1 - 1), _ref(nrhs), cf.ctypes.data_as(_dbl_p), _ref(w1),
                    x.ctypes.data_as(_dbl_p), _ref(max(n, 1)), ctypes.byref(info))
        info = info.value
    if info != 0:
        raise ValueError(f"band.solve: LAPACK dpbtrs argument {-info} is invalid")
    return x
