"""Tiny scenes and a CLI runner shared by the study tests."""
import json

from click.testing import CliRunner

from study.commands.cli import main

def moving_scene(frames: int = 4, size=(40, 24), segments: int = 12) -> str:
    """A ball moving over a checkered floor, direct light: the study tests' animated scene."""
    w, h = size
    return f"""
name = "tiny_moving"
transport = "direct"
frames = {frames}
ambient = [0.2, 0.2, 0.2]
background = [0.1, 0.1, 0.12]
resolution = {{ quick = [{w}, {h}], full = [{2 * w}, {2 * h}] }}
[camera]
position = [0.0, 0.5, 3.0]
target = [0.0, 0.3, 0.0]
yfov_deg = 40
[[objects]]
name = "ball"
mesh = {{ kind = "sphere", radius = 0.4, segments = {segments}, smooth = true }}
material = {{ albedo = [0.9, 0.4, 0.1] }}
transform = {{ translate = [-0.5, 0.4, 0.0] }}
motion = {{ velocity = [0.12, 0.0, 0.0] }}
[[objects]]
name = "floor"
mesh = {{ kind = "box", size = [6.0, 0.1, 6.0] }}
material = {{ albedo = [0.5, 0.5, 0.5], texture = {{ kind = "checker", squares = 24 }} }}
[[lights]]
type = "directional"
direction = [-0.3, -1.0, -0.5]
"""


MOVING = moving_scene()

STILL = """
name = "tiny_still"
transport = "unlit"
frames = 1
background = [0.1, 0.1, 0.12]
resolution = { quick = [36, 20], full = [72, 40] }
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
yfov_deg = 35
[[objects]]
name = "slab"
mesh = { kind = "box", size = [1.2, 0.7, 0.2] }
material = { albedo = [0.9, 0.8, 0.2] }
transform = { rotate_axis = [0.0, 0.0, 1.0], rotate_deg = 21.0 }
"""


def write_scenes(folder):
    (folder / "tiny_moving.toml").write_text(MOVING)
    (folder / "tiny_still.toml").write_text(STILL)
    return [str(folder / "tiny_moving.toml"), str(folder / "tiny_still.toml")]


def run_cli(args, code=0):
    r = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    assert r.exit_code == code, r.output
    return r


def run_tiny_study(root, *techniques, precision="per_pixel", pool=None):
    """A real study of the two tiny scenes under `root` (its own cache); returns its output folder.
    At 40x24 no reference reaches the figures' tolerances (960 pixels), so the per-pixel rule is
    the default here; tests/test_precision.py tests the figures' rule. `pool` (conftest's
    reference_pool): its cache starts with the references earlier tests rendered, and adds its own."""
    import pytest
    scenes = write_scenes(root)
    out = root / "out"
    args = ["run", "--scenes", ",".join(scenes), "--no-agreement", "--out", out, "--precision", precision]
    for t in techniques:
        args += ["--techniques", t]
    if pool is not None:
        pool.seed(root / "cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_CACHE", str(root / "cache"))
        run_cli(args)
    if pool is not None:
        pool.keep(root / "cache")
    return out


def quick_every_frame():
    """The quick profile with each ghosting frame's figures bounding its test, as the full profile's
    do: the quick profile bounds a ghosting test by its means over frames, under which the tiny
    scenes' ghosting tests settle at the probe, and a test of refining needs one that refines."""
    from dataclasses import replace
    from study.config.profile import get_profile
    q = get_profile("quick")
    return replace(q, precision=replace(q.precision, exemptions=()))


def summary(out):
    return json.loads((out / "manifest.json").read_text())["summary"]


TIMING_WORDS = ("ms / frame", "seconds", "ms /", "resolve ms", "raster ms")


def numbers(out):
    """Every table of a study except measured times (which differ run to run by nature)."""
    got = {}
    for p in sorted((out / "tables").glob("*.csv")):
        if p.stem in ("speed_error", "reference_convergence"):
            continue
        got[p.name] = [line for line in p.read_text().splitlines() if not line.startswith("ms / frame")]
    return got
