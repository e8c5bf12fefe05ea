"""Image metrics on arrays alone, importable without the study engine (as scikit-image's are):

  suite     MSE, RMSD, PSNR, SNR, relMSE, every metric of one image (all_metrics), temporal
            instability, and a whole sequence judged (judge_sequence)
  ssim      SSIM as scikit-image 0.26.0 computes it and MATLAB's volume SSIM, in Dr.Jit
  flip      LDR/HDR-FLIP as flip-evaluator 1.7 computes it, in Dr.Jit
  filters   the separable Dr.Jit filters both use
"""
