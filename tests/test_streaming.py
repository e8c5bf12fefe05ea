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
