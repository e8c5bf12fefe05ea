"""Where a ghosting test's reference chains start (study.engine.reuse_chain): instants the
figures' rule refined to one bound, scattered, chain through the instants between them where
those keep nearly all of their predecessors' pixels."""
from study.config.protocols import Protocol
from study.config.techniques import TechniqueConfig
from study.engine.plan import Planner
from study.engine.reuse_chain import bridge_by_kept, chain_reuse
from study.engine.tasks import Context, load_scene

BASE = dict(se_bound_lsb=4.0, target_noise_db=0.0, held_out=True, reuse=True)
FINER = {**BASE, "se_bound_lsb": 1.0}


def test_scattered_refined_instants_chain_through_a_cheap_gap_and_restart_after_a_dear_one():
    at = {t: FINER if t in (1, 4, 5, 9) else BASE for t in range(10)}
    # bridged when the gap (and the instant) costs at most 3 frames' worth: 1 -> 4, not 5 -> 9
    got = chain_reuse(at, (BASE,), bridge=lambda p, t: t - p <= 3)
    assert [got[t].get("reuse_since") for t in (1, 4, 5, 9)] == [1, 1, 1, 9]
    assert got[2] == got[3] == BASE and got[0] == BASE
    # without a bridge each run of consecutive refined instants starts its own chain
    plain = chain_reuse(at, (BASE,))
    assert [plain[t].get("reuse_since") for t in (1, 4, 5, 9)] == [1, 4, 4, 9]
    # a break in the scene times (not consecutive) is never bridged
    at2 = {t: FINER if t in (1, 4) else BASE for t in (0, 1, 2, 4)}
    assert chain_reuse(at2, (BASE,), bridge=lambda p, t: True)[4]["reuse_since"] == 4


def test_the_planner_bridges_on_sphere_ghosting_and_not_on_a_spinning_hairball(tmp_path):
    fx = [TechniqueConfig.parse("FXAA=fxaa")]
    proto = Protocol("ghosting", "ghosting", frames=6)
    for name, bridged in (("sphere_ghosting", True), ("hairball_rotating_unlit", False)):
        scene = load_scene(name)
        refined = {(name, "ghosting", t): FINER for t in (1, 3)}
        pl = Planner(Context(str(tmp_path), 1), BASE, None, refined, BASE)
        test = pl.add_test(name, scene, proto, fx, 32, 18)
        at = test.ref_settings_at
        assert at[1] == {**FINER, "reuse_since": 1} and at[2] == BASE
        assert at[3] == {**FINER, "reuse_since": 1 if bridged else 3}
        deps = pl.plan.tasks[test.reference_tasks[3]].deps
        # frame 3 keeps frame 2's pixels at its own bound: frame 2 at that bound is planned before it
        assert deps == ((pl.reference_key(scene, 2, 32, 18, {**FINER, "reuse_since": 1}),) if bridged else ())
    cost = bridge_by_kept(load_scene("sphere_ghosting"), 32, 18)
    assert cost(1, 3) and not cost(0, 20)
