"""The reference's settings and their defaults: one home for the renderer, the cache and the study.

  se_bound_lsb     every pixel's display-domain standard error (worst channel) at most this many
                   8-bit LSB, or the pixel hits the sample cap and is counted
  target_noise_db  the secondary target: the mean noise PSNR, 10 log10(1 / mean SE^2)
"""
SE_BOUND_LSB = 0.5
TARGET_NOISE_DB = 60.0

DEFAULTS = {"se_bound_lsb": SE_BOUND_LSB, "target_noise_db": TARGET_NOISE_DB}
