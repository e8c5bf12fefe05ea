"""The technique contract (taa_impl.contract): what a technique needs is data read without building
it, one entry point takes one Frame, a missing input is refused by name, and a researcher's technique
declared either way runs through the driver."""
import dataclasses

import numpy as np
import pytest

import taa_impl
from taa_impl import Frame, Inputs, Technique
from taa_impl.baseline import BaselineTAA
from taa_impl.ferrando import FerrandoTAA
from taa_impl.simple import NoAAParams

F = np.float32


def test_every_contract_is_read_without_building_the_technique(monkeypatch):
    """The registry, a preset and the planner read a technique's inputs from its class and
    parameters: with construction refused, every one is still known, and equals the built one's."""
    built = {name: taa_impl.make(name).inputs for name in taa_impl.TECHNIQUES}

    def refuse(self, *a, **k):
        raise AssertionError(f"{type(self).__name__} was built to read its contract")
    monkeypatch.setattr(Technique, "__init__", refuse)
    for name, entry in taa_impl.TECHNIQUES.items():
        assert entry.inputs_for() == built[name], name
    # per-parameter differences are data too: a preset's switches, the rejection buffers, Ferrando's ablation
    p = taa_impl.Preset("mine", BaselineTAA, reject_depth=0.1)
    assert p.needs == {"color", "depth", "motion", "prev_depth"} and p.sampling == "sequence"
    assert BaselineTAA.inputs_for(taa_impl.TAAParams(reject_id=True)).buffers == {"color", "depth", "motion", "object_id"}
    ablation = FerrandoTAA.inputs_for(taa_impl.FerrandoParams(motion_source="buffer"))
    assert (ablation.buffers, ablation.cameras) == ({"color", "motion"}, False)
    assert taa_impl.TECHNIQUES["taa_sparse"].inputs_for().extra_samples == 8
    assert taa_impl.TECHNIQUES["accumulation"].inputs_for(taa_impl.AccumulationParams(samples=5)).subframes == 5
    fsr = taa_impl.TECHNIQUES["fsr2"].inputs_for(taa_impl.FSR2Params(render_scale=0.67))
    assert (fsr.render_scale, fsr.jitter_period, fsr.upsamples, fsr.cameras) == (0.67, 17, True, True)
    assert taa_impl.FXAA.output_space == "display" and taa_impl.FXAA.inputs_for().display


def _buffers(h=6, w=8, seed=0):
    rng = np.random.default_rng(seed)
    return {"color": rng.uniform(0, 2, (h, w, 3)).astype(F), "depth": rng.uniform(1, 5, (h, w)).astype(F),
            "motion": rng.uniform(-1, 1, (h, w, 2)).astype(F)}


def test_one_frame_object_or_its_fields_as_keywords_give_one_image():
    a, b = taa_impl.make("taa_baseline"), taa_impl.make("taa_baseline")
    for k in range(3):
        bufs = _buffers(seed=k)
        fr = Frame(buffers=bufs, jitter=(0.25, -0.25), far=10.0, reset=k == 0)
        np.testing.assert_array_equal(a.process(fr), b.process(bufs, jitter=(0.25, -0.25), far=10.0, reset=k == 0))
    with pytest.raises(TypeError):
        a.process(_buffers(), far=10.0, jiter=(0, 0))     # a misspelt field is not silently dropped


@pytest.mark.parametrize("name, frame, words", [
    ("taa_baseline", dict(buffers={"color": np.zeros((4, 4, 3), F)}, far=1.0), "taa_baseline needs buffers ['depth', 'motion']"),
    ("taa_baseline", dict(buffers=_buffers(), far=float("nan")), "far must be finite and > 0"),
    ("taa_baseline", dict(buffers=_buffers(), far=1.0, jitter=(np.inf, 0)), "jitter must be finite"),
    ("fxaa", dict(buffers=_buffers(), far=1.0), "fxaa works on the display image: pass display="),
    ("taau", dict(buffers=_buffers(), far=1.0), "taau upsamples: pass output_size="),
    ("taau", dict(buffers=_buffers(), far=1.0, output_size=(8, 6)), "renders 4x3, got a 8x6 frame"),
    ("taa_ferrando_text", dict(buffers=_buffers(), far=1.0), "taa_ferrando_text needs the cameras"),
    ("fsr2", dict(buffers=_buffers(3, 4), far=1.0, output_size=(8, 6)), "fsr2 needs the cameras"),
    ("taa_sparse", dict(buffers=_buffers(), far=1.0), "taa_sparse needs supersampled="),
    ("taa_sparse", dict(buffers=_buffers(), far=1.0, supersampled=np.zeros((6, 8, 3)), mask=np.ones((6, 7), bool)),
     "mask has shape (6, 7), expected (6, 8)"),
])
def test_a_missing_or_malformed_input_is_refused_by_name(name, frame, words):
    with pytest.raises((ValueError, KeyError)) as e:
        taa_impl.make(name).process(Frame(**frame))
    assert words in str(e.value)


class NewStyle(Technique):
    """A researcher's technique in the contract's words: colour scaled by depth / far."""
    name = "depth_scaled"
    Params = NoAAParams
    contract = Inputs(buffers={"color", "depth"}, sampling="centre")

    def _clear_history(self):
        pass

    def _step(self, b, frame):
        return b["color"] * (b["depth"] / frame.far)


class OldStyle(Technique):
    """The same in the older spelling: class attributes and _step(b, width, height, far)."""
    name = "depth_scaled_old"
    Params = NoAAParams
    needs = frozenset({"color", "depth"})
    sampling = "centre"

    def _clear_history(self):
        pass

    def _step(self, b, w, h, far):
        assert (w, h) == (8, 6)
        return b["color"] * (b["depth"] / far)


@pytest.mark.parametrize("cls", [NewStyle, OldStyle])
def test_a_researchers_technique_in_either_spelling_has_one_contract(cls):
    assert cls.inputs_for() == Inputs(buffers={"color", "depth"}, sampling="centre")
    assert cls.needs == {"color", "depth"} and cls.sampling == "centre" and cls.output_space == "linear"
    bufs = _buffers()
    out = cls().process(bufs, far=4.0)
    np.testing.assert_allclose(out, bufs["color"] * (bufs["depth"] / F(4.0))[..., None], rtol=1e-6)


def test_the_driver_hands_a_researchers_technique_the_frame_its_contract_asks_for(tmp_path):
    """Through study.engine.drive: the raster renders the buffers the contract names, and the
    output is the technique's formula on them."""
    from study.config.protocols import static_schedule
    from study.config.techniques import TechniqueConfig
    from study.engine.drive import run_schedule
    from study.engine.tasks import load_scene
    from study_fixtures import write_scenes
    src = tmp_path / "mine.py"
    src.write_text("from taa_impl import Inputs, Technique\nfrom taa_impl.simple import NoAAParams\n\n\n"
                   "class Mine(Technique):\n    name = 'mine'\n    Params = NoAAParams\n"
                   "    contract = Inputs(buffers={'color', 'depth'}, sampling='centre')\n\n"
                   "    def _clear_history(self):\n        pass\n\n"
                   "    def _step(self, b, frame):\n        return b['color'] * 0.0 + b['depth']\n")
    _, still = write_scenes(tmp_path)
    scene = load_scene(still)
    configs = [TechniqueConfig.parse(f"M={src}:Mine"), TechniqueConfig.parse("N=noaa")]
    out = run_schedule(scene, 24, 16, static_schedule(0, 1, [1]), configs, {}, progress=False)
    (img,) = out["M"]["images"].values()
    from raster import Rasterizer
    r = Rasterizer(scene, 24, 16)
    try:
        depth = r.render(0, (0.0, 0.0), ("color", "depth"), prev_t=0)["depth"]
    finally:
        r.close()
    np.testing.assert_array_equal(img, np.repeat(depth[..., None], 3, axis=-1))
    assert dataclasses.asdict(taa_impl.make("noaa").inputs)["buffers"] == {"color"}


def test_a_study_column_reads_its_contract_and_key_without_building_the_technique(monkeypatch):
    """study.config.techniques.TechniqueConfig: the parameters, inputs, class and key data a planner
    reads of a column (a preset, overrides, a feedback preset, an upscaler's render scale) are the
    built technique's, with construction refused."""
    from study.config.techniques import TechniqueConfig
    cols = [TechniqueConfig.parse(x) for x in (
        "taa_baseline", "taa_tonemap_blend", "taa_variance:sharpen=none", "Mine=taa_ycocg:k_min=0.5",
        "taa_baseline:feedback=inside", "fsr2:render_scale=0.5", "upscale_spatial", "fxaa", "accumulation:samples=5",
        "taa_reject", "taa_sparse")]
    built = {c.label: (c.make().params, c.make().inputs, type(c.make())) for c in cols}
    keys = {c.label: c.key_data() for c in cols}

    def refuse(self, *a, **k):
        raise AssertionError(f"{type(self).__name__} was built to read its contract")
    monkeypatch.setattr(Technique, "__init__", refuse)
    for c in cols:
        assert (c.params(), c.inputs(), c.code()) == built[c.label], c.label
        assert c.key_data() == keys[c.label], c.label
    assert TechniqueConfig.parse("fsr2:render_scale=0.5").inputs().render_scale == 0.5
    assert TechniqueConfig.parse("fxaa").inputs().display
