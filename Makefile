# jaxmotion: make setup | test | train EXP=<name> ARGS="k=v ..." | eval RUN=<run-folder> | bench | demo | lint
PY ?= .venv/bin/python
EXP ?= smoke
ARGS ?=
RUN ?=
BENCH_ARGS ?=
STAMP := .venv/.installed
# Motion clips: $JAXMOTION_DATA if set, else ./data, else the shared clips beside the repo.
JAXMOTION_DATA ?= $(if $(wildcard data),data,$(if $(wildcard ../shared/motions),$(abspath ../shared/motions),data))
export JAXMOTION_DATA

.PHONY: setup test train eval bench demo lint clean

setup: $(STAMP)

# Reinstall only when pyproject.toml is newer than the last install.
$(STAMP): pyproject.toml
	command -v $(PY) >/dev/null || python3 -m venv .venv
	$(PY) -m pip install -e '.[test]'
	touch $(STAMP)

test: $(STAMP)
	JAX_DISABLE_JIT=1 $(PY) -m pytest -q

train: $(STAMP)
	$(PY) -m jaxmotion.train $(EXP) $(ARGS)

eval: $(STAMP)
	@test -n "$(RUN)" || { echo "usage: make eval RUN=runs/<name>/<timestamp>"; exit 2; }
	$(PY) -m jaxmotion.eval $(RUN)

bench: $(STAMP)
	$(PY) -m jaxmotion.bench $(BENCH_ARGS)

# A first look: the shipped Table 1 policy, evaluated briefly, as a video and a 3D replay page.
DEMO ?= pretrained/chest_open+squat_cpu
demo: $(STAMP)
	$(PY) -m jaxmotion.eval $(DEMO) --episodes 1 --steps 150 --no-plots --json demo/metrics.json --video demo/demo.mp4 --html demo/demo.html

lint: $(STAMP)
	$(PY) -m ruff check jaxmotion tests experiments
	$(PY) -m ruff format --check jaxmotion tests experiments

clean:
	rm -rf build dist *.egg-info .pytest_cache
	find . -name __pycache__ -type d -not -path './.venv/*' -prune -exec rm -rf {} +
