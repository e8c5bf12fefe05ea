"""The cost model of speed against error (README "Cost"): samples shaded per pixel times the raster
time of one sample per pixel, plus the extra samples' shading, plus the technique's own resolve."""
import pytest

from display import DisplayTransform
from scenes import get_scene
from study.config.techniques import TechniqueConfig
from study.engine import costs
from study_fixtures import moving_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "tiny.toml"
    path.write_text(moving_scene(frames=2, size=(32, 18), segments=8))
    return get_scene(str(path))


def test_samples_per_pixel_and_the_total(scene):
    import numpy as np
    configs = [TechniqueConfig("No AA", "noaa"), TechniqueConfig("SSAA 4x", "accumulation", (("samples", 4),)),
               TechniqueConfig("TAA", "taa_baseline"), TechniqueConfig("Sparse", "taa_sparse")]
    disp = {0: DisplayTransform.from_reference(np.full((18, 32, 3), 0.5, np.float32))}
    got = costs.measure(scene, 32, 18, configs, disp, {"Sparse": 0.25})
    spp = {label: c["samples_per_pixel"] for label, c in got.items()}
    # one centre or jittered sample for No AA and a TAA; N sub-frames for SSAA N; sparse
    # supersampling 1 plus the extra samples per pixel its run shaded on average (0.25 here)
    assert spp == {"No AA": 1.0, "SSAA 4x": 4.0, "TAA": 1.0, "Sparse": pytest.approx(1.0 + 0.25)}
    for label, c in got.items():
        n = 4 if label == "SSAA 4x" else 1
        assert c["total_ms"] == pytest.approx(n * c["raster_ms"] + c["extra_ms"] + c["resolve_ms"], rel=1e-12)
        assert c["raster_ms"] > 0 and c["resolve_ms"] > 0
    assert got["Sparse"]["extra_ms"] > 0 and got["TAA"]["extra_ms"] == 0


def test_columns_reading_the_same_buffers_share_one_rasteriser_and_its_timing(scene):
    import numpy as np
    configs = [TechniqueConfig("TAA", "taa_baseline"), TechniqueConfig("TAA, no sharpen", "taa_baseline", (("sharpen", "none"),)),
               TechniqueConfig("No AA", "noaa")]
    disp = {0: DisplayTransform.from_reference(np.full((18, 32, 3), 0.5, np.float32))}
    sources = costs.Sources()
    try:
        got = {c.label: costs.measure(scene, 32, 18, [c], disp, {}, sources)[c.label] for c in configs}
        # the two TAAs read the same buffers: one source, one timing; No AA reads colour alone: its own
        assert len(sources._by) == 2
        assert got["TAA"]["raster_ms"] == got["TAA, no sharpen"]["raster_ms"]
        assert got["No AA"]["raster_ms"] != got["TAA"]["raster_ms"]
    finally:
        sources.close()
    assert sources._by == {}


def test_a_supersampling_resolve_is_timed_on_a_few_rendered_sub_frames(scene):
    """The resolve of N sub-frames (a mean) is timed on copies of DISTINCT_SUBFRAMES rendered ones,
    not on N renders made twice (a warm-up drive, then the list): 2 x 128 raster frames a scene
    for the thesis's accumulation were most of the quick study's serial cost measurement."""
    import numpy as np
    disp = {0: DisplayTransform.from_reference(np.full((18, 32, 3), 0.5, np.float32))}
    sources = costs.Sources()
    try:
        got = costs.measure(scene, 32, 18, [TechniqueConfig("SSAA 32x", "accumulation", (("samples", 32),))],
                            disp, {}, sources)["SSAA 32x"]
        (src, _), = sources._by.values()
        assert src.rendered == 4, src.rendered
        assert costs.DISTINCT_SUBFRAMES == 4
    finally:
        sources.close()
    assert got["samples_per_pixel"] == 32.0 and got["resolve_ms"] > 0
    assert got["total_ms"] == pytest.approx(32 * got["raster_ms"] + got["resolve_ms"], rel=1e-12)
