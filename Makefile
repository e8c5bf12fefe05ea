# The two commands of the README: `make study` and `make test`. Both set up what is missing first.
PY := .venv/bin/python
STAMP := .venv/.setup-stamp

.PHONY: study test setup clean-cache

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

study: $(STAMP)
	$(PY) -m study run --profile quick

test: $(STAMP)
	$(PY) -m pytest -q

clean-cache:
	rm -rf .cache/taa-study
