"""The camera's sensor: :mod:`.model` (radiance image → digital numbers: PSF, shot and read noise, full well, gain,
bias, ADC) and :mod:`.noise` (per-pixel counter-based noise draws, Philox4x64-10)."""
