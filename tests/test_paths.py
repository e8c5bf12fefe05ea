"""Files the commands find beside the code: moving a module must not lose them silently."""
from pathlib import Path

from study.commands import bench
from study.commands.study_commands import PAPER_DIR
from study.config.studyfile import PROFILE_DIR, builtin_profiles
from study.reporting import html_report, thesis

ROOT = Path(__file__).resolve().parent.parent


def test_the_paper_command_builds_the_checkout_s_paper():
    assert PAPER_DIR == ROOT / "paper" and (PAPER_DIR / "main.tex").is_file()


def test_bench_finds_its_numpy_oracle():
    mod = bench._oracle_module()       # None would drop the oracle column without a word
    assert mod is not None and hasattr(mod, "OracleTAA")


def test_profiles_templates_and_thesis_figures_are_found():
    assert builtin_profiles() == ["full", "quick", "thesis"] and PROFILE_DIR == ROOT / "study" / "config" / "profiles"
    assert thesis.FIGURES_FILE.is_file()
    assert (Path(html_report.__file__).parent / "templates" / "report.html.j2").is_file()
