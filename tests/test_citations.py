"""Every citation in the sources is one a reader can follow: a published source or a file of the
repository, never a document the repository does not hold (a "spec section", a numbered "seed",
an "issue" of a tracker not named)."""
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SUFFIXES = (".py", ".toml", ".j2", ".js", ".sh", ".tex", ".md")

# Each pattern is a kind of citation of a document outside the repository.
ABSENT = re.compile(
    r"\bspec(?:ification)?(?:'s)?\s+(?:section\s*|§\s*)\d"   # "spec section 8", "spec §5"
    r"|\bseeds?\s+00\d\b"                                   # "seed 002"
    r"|\bseeds/"                                            # a path into the source documents' folder
    r"|study-spec"                                          # the background notes' file name
    r"|(?<!github )(?<![\w/#.-])issues?\s+#?\d+\b",         # "issue 9", "Issue 11", "issue #12"
    re.IGNORECASE)


def absent_citations(text: str) -> list[tuple[int, str]]:
    """(line number, line) of each line of `text` that cites an absent document."""
    return [(i, line.strip()) for i, line in enumerate(text.splitlines(), start=1) if ABSENT.search(line)]


@pytest.mark.parametrize("line", [
    "The display transform (spec section 8), applied once", "INSIDE's box (spec §5 step 3).",
    "Spec section 5, plus the switches", "(spec's section 9)", "sparse supersampling (seed 002)",
    "Seed 003's L_white", "see /work/shared/seeds/003_x.txt", "read STUDY-SPEC.md first",
    "Adaptive references (issue 9): the", "Issue 11, validation at the boundary", "as in issue #12",
    "issues 20 and 21"])
def test_a_citation_of_an_absent_document_is_found(line):
    assert absent_citations(f"x = 1\n# {line}\n") == [(2, f"# {line}")]


@pytest.mark.parametrize("line", [
    "https://github.com/mitsuba-renderer/mitsuba3/issues/123", "mitsuba3's GitHub issue #1234",
    "Oliveros 2018, Improved Sampling for Temporal Anti-Aliasing, §4.3", "two seeds of pipe's reference",
    "rng = np.random.default_rng(seed=7)", "the random seed 7", "the glTF 2.0 specification, Appendix B",
    'spec = "No AA=noaa"', "an issue with 8-bit PNGs", "TAAParams (taa_impl/baseline.py)", "docs/method.md, §2"])
def test_a_followable_citation_or_plain_text_is_not_flagged(line):
    assert absent_citations(line) == []


def test_no_tracked_source_cites_an_absent_document():
    try:
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True, check=True,
                                timeout=60).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: no list of tracked files")
    this = Path(__file__).resolve().relative_to(ROOT).as_posix()
    found = []
    for rel in listed:
        path = ROOT / rel
        if not rel.endswith(SUFFIXES) or rel == this or not path.is_file():
            continue
        found += [f"{rel}:{i}: {line}" for i, line in absent_citations(path.read_text(errors="replace"))]
    assert not found, "cite a published source or a file under docs/ instead:\n" + "\n".join(found)
