"""The study's defaults, each in one place: the protocols, the profiles' settings, the study file's
fields and the command line read them from here (the reference's own are references.settings)."""
from references import settings as _reference

# The thesis keeps frame 16 after a reset (its static protocol, a cold start).
THESIS_HISTORY = 16
# The study's static run: 256 frames of history (with k_max = 0.979 the first frame weighs 0.4 %),
# judged at log-spaced history lengths.
STATIC_HISTORY = 256
STATIC_CHECKPOINTS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
# The ghosting test: judged frames (capped by the scene's own) and unjudged warm-up frames.
GHOSTING_FRAMES = 24
GHOSTING_WARMUP = 0

REFERENCE = dict(_reference.DEFAULTS)          # se_bound_lsb, target_noise_db
# Raster frames the agreement check averages. Fewer leave the raster's own integration error in the
# figure: moire at 320x180 against a 0.5-LSB reference 42.6 dB at 64, 52.4 at 256, 60.8 at 1024.
AGREEMENT_SAMPLES = 256
AGREEMENT_TARGET_NOISE_DB = _reference.TARGET_NOISE_DB
# what a scene's raster-against-reference check must reach (study.engine.agreement)
AGREEMENT_TARGETS = {"agreement_psnr_db": 45.0, "interior_max_abs_err": 1e-4, "reference_noise_psnr_db": 55.0}
SWEEP_SCENES = ("sphere_ghosting", "disocclusion")   # where the sparse-supersampling mu sweep runs
# The sharpen strength sweep (a factor of the thesis's figures): both thesis TAAs at each strength w
# of the cross kernel (0 none, 0.25 the normalised kernel, 1 Xu's), at the thesis's history, on the
# thesis's static scenes (those of study/reporting/thesis_figures.toml).
SHARPEN_SWEEP_SCENES = ("pipe", "pipe_tilted", "blinds", "arched_window", "atrium", "flowers", "hard_edges",
                        "hairball_unlit", "hairball_lit")
GHOSTING_SKIP = ("accumulation",)              # N sub-frames per frame: too slow for sequences
KEEP_FRAMES = "report"                         # a run keeps, once judged, the frames the report reads
# A study file that lists no techniques compares this built-in profile's: the thesis's columns,
# both TAAs without their sharpen, Li, Chen, Zhang 2021's and Ferrando 2018's TAAs.
DEFAULT_TECHNIQUES_PROFILE = "quick"
# Precision set by the figures (study.engine.precision): each figure's reference uncertainty at
# most its tolerance (relative: MSE-like figures, 0.0023 = 0.01 dB of PSNR; relmse: the linear
# relMSE, a fraction of it: printed to 3 significant digits, it is the secondary HDR figure), each
# test's references probed at the start bound, then rendered at the bound the figures ask for, down
# to the finest. 8 LSB: a probe costs a few times the pilot's 8 samples per pixel.
PRECISION = {"rule": "figures", "psnr_db": 0.01, "ssim": 1e-4, "flip": 1e-4, "relative": 0.0023, "relmse": 0.01,
             "start_bound_lsb": 8.0, "finest_bound_lsb": 0.125, "confirm": False}
# The perceptual video metric (study.metrics.video): ColorVideoVDP on cvvdp's 24-inch full-HD
# office monitor (200 cd/m^2, 250 lux, 0.6 m), the display class the thesis's 1600x900 frames were
# made for, played at 60 fps, the frame rate a game's TAA is tuned at. A technique-frame costs
# ~0.2-0.4 s at 320x180 and ~6 s at 1600x900 on a core here: by default it judges the ghosting tests.
VIDEO = {"metric": "cvvdp", "display": "standard_fhd", "fps": 60.0, "tests": ("ghosting",), "device": "auto"}
