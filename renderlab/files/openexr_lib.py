"""OpenEXR library settings that its Python binding does not expose, set through the binding's own shared library.

The ZIP level of :func:`renderlab.files.imageio.write_exr` (``Imf::setDefaultZipCompressionLevel``) and the threads
that compress a file's line blocks (``Imf::setGlobalThreadCount``). Both are global to that library; a missing
symbol leaves the library's default (lossless all the same).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os

import OpenEXR


@functools.cache
def imf_setter(fn_name: str):
    """OpenEXR's C++ ``Imf::<fn_name>(int)`` from the OpenEXR module's own library, or None where it is not exported
    (the file is then written with the library's default: lossless all the same). The Python binding passes neither
    the ZIP level (a ``zipCompressionLevel`` key of the header dict is written as a plain int attribute and the level
    stays 4) nor a thread count; both settings are global to that library."""
    major, minor = str(OpenEXR.OPENEXR_VERSION).split(".")[:2]
    ns = f"Imf_{major}_{minor}"
    name = f"_ZN{len(ns)}{ns}{len(fn_name)}{fn_name}Ei"  # Itanium C++ name of Imf::<fn_name>(int)
    try:
        fn = getattr(ctypes.CDLL(OpenEXR.__file__), name)
    except (OSError, AttributeError):
        return None
    fn.argtypes, fn.restype = [ctypes.c_int], None
    return fn


def zip_level_setter():
    """``Imf::setDefaultZipCompressionLevel`` (:func:`imf_setter`): every ZIP file written through the ``OpenEXR``
    module afterwards in this process uses the level."""
    return imf_setter("setDefaultZipCompressionLevel")


def exr_threads() -> int:
    """Threads that compress an EXR's line blocks: the CPUs this process may use (the blocks are compressed
    independently and written in order, so the file's bytes do not depend on it)."""
    return max(1, len(os.sched_getaffinity(0)))


@contextlib.contextmanager
def compression_threads(n: int):
    """OpenEXR's global thread pool at ``n`` threads inside the block and at none after it: no pool thread outlives a
    write, so a process forked later (a ``ProcessPoolExecutor`` worker) never inherits a pool without its threads.
    On the 2-core machine a 1 MP ten-channel ZIP file takes 0.18-0.20 s instead of 0.28-0.32 s, the same bytes
    (a one-off probe)."""
    setter = imf_setter("setGlobalThreadCount") if n > 1 else None
    if setter is None:
        yield
        return
    setter(n)
    try:
        yield
    finally:
        setter(0)
