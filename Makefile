# The two commands of the README: `make study` and `make test`. Both set up what is missing first.
PY := .venv/bin/python
# Every process of a study or of the suite (xdist workers, Dask workers, the CLI's subprocesses)
# would compile torch, Mitsuba's and Dask's Python from source again where the environment turns
# bytecode off (PYTHONDONTWRITEBYTECODE=1, as on this project's build machines): written once instead.
export PYTHONDONTWRITEBYTECODE :=
STAMP := .venv/.setup-stamp

.PHONY: study thesis test setup clean-cache paper results

$(STAMP): pyproject.toml scripts/setup.sh scripts/apt_install.sh
	bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

study: $(STAMP)
	$(PY) -m study run --profile quick

# The thesis's own study at its 1600x900 (study/config/profiles/thesis.toml; docs/guide.md). Long:
# THESIS_ARGS="--stop-after 2h" stops it on time (exit 3), and `make thesis` again resumes it.
thesis: $(STAMP)
	$(PY) -m study run --profile thesis $(THESIS_ARGS)

# docs/results.md and the README's results block (taa-study results): from the thesis study's out/thesis
# where it is finished (`make thesis`), else from the quick study's out/quick; RESULTS_ARGS="--source quick" forces one.
results: $(STAMP)
	$(PY) -m study results $(RESULTS_ARGS)

# The suite builds the paper: TeX is installed first, and a PDF test that finds no TeX fails
# instead of skipping (TAA_REQUIRE_LATEX). It runs in TEST_WORKERS processes (pytest-xdist; the
# cores, at most 4: each process holds its own Mitsuba and Dr.Jit), a test file per process at a
# time so that module fixtures are made once; TEST_WORKERS=0 runs it in this process.
TEST_WORKERS ?= $(shell n=$$(nproc); [ $$n -gt 4 ] && n=4; echo $$n)
test: $(STAMP)
	bash scripts/setup_latex.sh
	TAA_REQUIRE_LATEX=1 $(PY) -m pytest -q --durations=20 -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# A LaTeX toolchain when missing (scripts/setup_latex.sh, as `make test`), then
# `taa-study paper`: the thesis study's finished out/thesis where there is one (`make thesis`; read as
# it is), else the quick study (make-style, cached); its tables and figures into paper/generated/,
# and paper/main.pdf. PAPER_ARGS passes options, e.g. PAPER_ARGS="--source quick" or "--scenes pipe,blinds"
# (the quick study of those scenes).
paper: $(STAMP)
	bash scripts/setup_latex.sh
	$(PY) -m study paper $(PAPER_ARGS)
	@test -s paper/main.pdf || { echo "make paper: paper/main.pdf was not built" >&2; exit 1; }
	@pdfinfo paper/main.pdf | grep -E '^Pages:' | sed 's/^/paper\/main.pdf: /'

clean-cache:
	rm -rf .cache/taa-study
