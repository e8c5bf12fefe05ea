"""The TAA study, in layers; each imports only those above it in this list (tests/test_layers.py):

  metrics     image metrics on arrays alone: SSIM, volume SSIM, FLIP, the thesis's metrics
  config      what a study compares: techniques, protocols, profiles, study files, defaults
  engine      plan -> tasks -> execute -> store: references, runs, metrics, agreement, costs
  reporting   tables, figures, the HTML report and the paper, from the engine's results alone
  commands    the `taa-study` command line: run, ab, bench, estimate, paper, ...
"""
