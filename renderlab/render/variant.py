"""Selecting and initialising the Mitsuba 3 variant.

Mitsuba 3.9 / Dr.Jit 1.5 LLVM variants crash on LLVM 15 ("Cannot select: fmaximum"); with
Debian's ``libllvm19`` they work. :func:`init_mitsuba` points Dr.Jit at LLVM 19 (unless the
user already set ``DRJIT_LIBLLVM_PATH``), selects the requested variant and falls back with a warning:
a CUDA variant without a GPU to the LLVM variant of the same colour, an LLVM variant without a usable
LLVM to ``scalar_rgb``.
The import of mitsuba happens here, inside the function, so ``renderlab --help`` stays instant.

``RENDERLAB_MITSUBA_DEVICE=cuda`` in the environment turns every request for ``llvm_ad_<colour>`` into
``cuda_ad_<colour>`` (same fallback chain), so a scenario, a test run or a benchmark goes to the GPU
without editing it (``benchmarks/gpu_check.sh``). Every JIT variant takes the same render path
(:mod:`renderlab.render.mitsuba_rays`); only ``scalar_rgb`` traces rays from Python.
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

#: requested variant → the variant in use for it in this process (itself or its fallback)
_resolved: dict[str, str] = {}


def find_llvm19() -> str | None:
    """Return the path of an LLVM 19 shared library, or None."""
    for path in LLVM_CANDIDATES:
        if os.path.exists(path):
            return path
    hits = sorted(glob.glob("/usr/lib/*/libLLVM*19*.so*"))
    return hits[0] if hits else None


def fallbacks(variant: str) -> list[str]:
    """The variants tried after ``variant``, in order: CUDA → the LLVM variant of the same colour → ``scalar_rgb``."""
    colour = variant.rsplit("_", 1)[-1]
    chain = [f"llvm_ad_{colour}"] if variant.startswith("cuda") else []
    return chain + (["scalar_rgb"] if variant != "scalar_rgb" else [])


def _why(variant: str, exc: Exception) -> str:
    """Why ``variant`` failed and what would fix it (one line)."""
    what = " ".join(str(exc).split()) or type(exc).__name__
    if variant.startswith("cuda"):
        return f"no usable CUDA GPU or driver ({what})"
    return f"{what}; install Debian's libllvm19 (./setup.sh does) or set DRJIT_LIBLLVM_PATH"


def device_variant(variant: str, device: str | None = None) -> str:
    """``variant`` on the device named by ``device`` (default ``$RENDERLAB_MITSUBA_DEVICE``): ``cuda`` maps
    ``llvm_ad_<colour>`` to ``cuda_ad_<colour>``; ``llvm`` maps ``cuda_ad_<colour>`` to ``llvm_ad_<colour>``;
    unset or empty leaves it unchanged. Any other value is a UserError."""
    device = os.environ.get("RENDERLAB_MITSUBA_DEVICE", "") if device is None else device
    if device not in ("", "cuda", "llvm"):
        raise UserError(f"RENDERLAB_MITSUBA_DEVICE must be cuda or llvm, got {device!r}")
    if device and variant.startswith(("llvm_ad_", "cuda_ad_")):
        return f"{device}_ad_{variant.rsplit('_', 1)[-1]}"
    return variant


def init_mitsuba(variant: str = "llvm_ad_mono"):
    """Import mitsuba, select ``variant`` (falling back with a warning) and return the module.

    A CUDA variant without a usable GPU falls back to the LLVM variant of the same colour (CPU, vectorised);
    an LLVM variant without a usable LLVM to ``scalar_rgb`` (about 10x slower). The choice is made once per
    process and requested variant, so the warning is issued once.

    Parameters
    ----------
    variant : str
        One of ``llvm_ad_mono``, ``llvm_ad_rgb``, ``scalar_rgb``, ``cuda_ad_mono``, ``cuda_ad_rgb``.

    Returns
    -------
    module
        The ``mitsuba`` module with the variant set. ``mitsuba.variant()`` tells which one is active.
    """
    if variant not in KNOWN_VARIANTS:
        raise UserError(f"render.variant must be one of {', '.join(KNOWN_VARIANTS)}, got {variant!r}")
    variant = device_variant(variant)
    if variant != "scalar_rgb" and "DRJIT_LIBLLVM_PATH" not in os.environ:  # CUDA may fall back to LLVM
        lib = find_llvm19()
        if lib:
            os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import mitsuba as mi

    if variant in _resolved:
        mi.set_variant(_resolved[variant])
        return mi
    errors = []
    for candidate in [variant, *fallbacks(variant)]:
        try:
            mi.set_variant(candidate)
        except Exception as exc:  # the CUDA/LLVM backend is missing or broken on this machine
            from renderlab.files.signals import raise_pending

            raise_pending()  # a SIGTERM/SIGINT raised inside Mitsuba's start-up comes back as an error: end, no advice
            errors.append(f"{candidate}: {_why(candidate, exc)}")
            continue
        if errors:
            slow = " (about 10x slower)" if candidate.startswith("scalar") else " (CPU)"
            warnings.warn(f"Mitsuba variant {variant} is not usable here ({'; '.join(errors)}); "
                          f"falling back to {candidate}{slow}", RuntimeWarning, stacklevel=2)
        _resolved[variant] = candidate
        return mi
    raise UserError(f"no Mitsuba variant is usable here: {'; '.join(errors)}")
