"""Selecting and initialising the Mitsuba 3 variant.

Mitsuba 3.9 / Dr.Jit 1.5 LLVM variants crash on LLVM 15 ("Cannot select: fmaximum"); with
Debian's ``libllvm19`` they work. :func:`init_mitsuba` points Dr.Jit at LLVM 19 (unless the
user already set ``DRJIT_LIBLLVM_PATH``), selects the requested variant and falls back to the
matching ``scalar_*`` variant with a warning when the LLVM backend is not usable.
The import of mitsuba happens here, inside the function, so ``renderlab --help`` stays instant.
"""

from __future__ import annotations

import glob
import os
import warnings

from renderlab.errors import UserError

LLVM_CANDIDATES = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/aarch64-linux-gnu/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so",
)
KNOWN_VARIANTS = ("llvm_ad_mono", "llvm_ad_rgb", "scalar_rgb", "cuda_ad_mono", "cuda_ad_rgb")
# The PyPI wheel has no scalar_mono: mono scenes fall back to scalar_rgb, and the backend averages
# the (equal, for grey albedo and sun) channels back to one.

_active: str | None = None


def find_llvm19() -> str | None:
    """Return the path of an LLVM 19 shared library, or None."""
    for path in LLVM_CANDIDATES:
        if os.path.exists(path):
            return path
    hits = sorted(glob.glob("/usr/lib/*/libLLVM*19*.so*"))
    return hits[0] if hits else None


def init_mitsuba(variant: str = "llvm_ad_mono"):
    """Import mitsuba, select ``variant`` (falling back to scalar with a warning) and return the module.

    Parameters
    ----------
    variant : str
        One of ``llvm_ad_mono``, ``llvm_ad_rgb``, ``scalar_rgb``, ``cuda_ad_mono``, ``cuda_ad_rgb``.

    Returns
    -------
    module
        The ``mitsuba`` module with the variant set. ``mitsuba.variant()`` tells which one is active.
    """
    global _active
    if variant not in KNOWN_VARIANTS:
        raise UserError(f"render.variant must be one of {', '.join(KNOWN_VARIANTS)}, got {variant!r}")
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        lib = find_llvm19()
        if lib:
            os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import mitsuba as mi

    if _active == variant:
        mi.set_variant(variant)
        return mi
    try:
        mi.set_variant(variant)
    except Exception as exc:  # the LLVM/CUDA backend is missing or broken on this machine
        fallback = "scalar_rgb"
        warnings.warn(
            f"Mitsuba variant {variant} is not usable here ({exc}); falling back to {fallback}, "
            "which is about 10x slower. Install Debian's libllvm19 (./setup.sh does).",
            RuntimeWarning,
            stacklevel=2,
        )
        mi.set_variant(fallback)
        variant = fallback
    _active = variant
    return mi
