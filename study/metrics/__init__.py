"""Image metrics on arrays alone, importable without the study engine (as scikit-image's are):

  suite        MSE, RMSD, PSNR, SNR, relMSE, SSIM and FLIP of one image pair
  judging      every metric of one image (all_metrics, all_metrics_against) and a whole run
               judged (judge_run)
  temporal     temporal instability of a frame sequence
  ssim         SSIM as scikit-image 0.26.0 computes it and MATLAB's volume SSIM, in Dr.Jit
               (Wang et al. 2004); ssim_window its Gaussian windows, ssim_passes its Dr.Jit passes,
               ssim_against one image against several references
  flip         LDR/HDR-FLIP as flip-evaluator 1.7 computes it, in Dr.Jit (Andersson et al. 2020, 2021);
               flip_colour its constants and colour pipeline, flip_passes its Dr.Jit passes
  video        ColorVideoVDP, the perceptual video metric (Mantiuk et al. 2024)
  uncertainty  each figure's uncertainty from the reference's two halves (the jackknife)
  filters      the separable Dr.Jit filters SSIM and FLIP use
  checks       what a metric can judge, refused up front with what it expected: 8-bit figures and
               SSIM's default range take uint8 images, float SSIM needs an explicit data_range,
               FLIP LDR display images in [0, 1] (or uint8), HDR-FLIP linear images >= 0; NaN/Inf
               and mismatched shapes or kinds are named
"""
