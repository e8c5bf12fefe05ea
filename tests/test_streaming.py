"""Runs hand each judged frame on as it is made (study.engine.drive.run_schedule's emit): a 100-frame
sequence of ten techniques at 1600x900 would otherwise hold 17 GB."""
import numpy as np

from study_fixtures import moving_scene


def test_emit_gets_every_judged_frame_in_order_and_nothing_is_held(tmp_path):
    from scenes import get_scene
    from study.config.techniques import TechniqueConfig
    from study.engine.drive import run_schedule
    from study.config.protocols import Protocol

    path = tmp_path / "m.toml"
    path.write_text(moving_scene(frames=5, size=(24, 16)))
    scene = get_scene(str(path))
    proto = Protocol("ghosting_warm", "ghosting", frames=5, warmup=3)
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]
    held = run_schedule(scene, 24, 16, proto.schedule(scene), configs, {}, progress=False)
    got = []
    streamed = run_schedule(scene, 24, 16, proto.schedule(scene), configs, {}, progress=False,
                            emit=lambda label, f, img: got.append((label, f, img)))
    assert all(not r["images"] for r in streamed.values())
    for label in ("taa_baseline", "noaa"):
        mine = [(f, img) for l, f, img in got if l == label]
        assert [f for f, _ in mine] == list(range(5)) == sorted(held[label]["images"])
        assert all(np.array_equal(img, held[label]["images"][f]) for f, img in mine)


def test_a_supersampling_column_reads_its_sub_frames_one_at_a_time_and_gets_their_mean(tmp_path, monkeypatch):
    """Accumulation's sub-frames are rendered as the technique reads them and not kept (held at once,
    128 of them at 1600x900 took about 6 GB), and the output is still the float64 mean of exactly
    those frames, each rendered with every buffer as a sequence column's would be."""
    import weakref

    from raster import Rasterizer
    from scenes.jitter import halton_offset
    from study.config.protocols import static_schedule
    from study.config.techniques import TechniqueConfig
    from study.engine import drive
    from study.engine.tasks import load_scene
    from study_fixtures import write_scenes

    _, still = write_scenes(tmp_path)
    scene = load_scene(still)
    alive, peak = [], [0]
    real = drive.FrameSource.transient

    def counted(self, *a, **k):
        peak[0] = max(peak[0], sum(r() is not None for r in alive))   # earlier sub-frames still held
        got = real(self, *a, **k)
        alive.append(weakref.ref(got["color"]))
        return got
    monkeypatch.setattr(drive.FrameSource, "transient", counted)
    configs = [TechniqueConfig.parse("A=accumulation:samples=8"), TechniqueConfig.parse("U=taa_baseline")]
    out = drive.run_schedule(scene, 24, 16, static_schedule(0, 1, [1]), configs, {}, progress=False)
    assert len(alive) == 8 and peak[0] <= 1
    (img,) = out["A"]["images"].values()
    r = Rasterizer(scene, 24, 16)
    try:
        subs = [r.render(0, halton_offset(j, 8), ("color", "depth", "motion"), prev_t=0)["color"] for j in range(8)]
    finally:
        r.close()
    want = (np.sum(np.asarray(subs, np.float64), axis=0) * (1.0 / 8)).astype(np.float32)
    np.testing.assert_allclose(img, want, rtol=1e-6, atol=1e-7)
