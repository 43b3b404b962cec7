# drillgym — set-up and checks. `make demo` and `make test` are all a new user needs.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= results/demo

.PHONY: demo test lint format type pytest realtime install clean mutation

# torch is installed first, as its CPU build: an unpinned torch would pull a multi-GB CUDA build. Where pip
# finds no CPU wheel of its own (an ordinary machine), take it from PyTorch's CPU index:
#   make test TORCH_INDEX=https://download.pytorch.org/whl/cpu
TORCH       ?= torch==2.13.0
TORCH_INDEX ?=

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX)) "$(TORCH)"
	$(PY) -m pip install --quiet --disable-pip-version-check -e ".[dev]"
	$(PY) -m drillgym.envs.compiled
	$(PY) -m drillgym.controllers.compiled
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/drillgym demo --out $(OUT)

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

type: $(STAMP)
	$(VENV)/bin/mypy

pytest: $(STAMP)
	$(PY) -m pytest -n 2 --dist loadfile -m "not realtime"
	@$(MAKE) --no-print-directory realtime

realtime: $(STAMP)
	@# The realtime tests after the rest, in two processes: the whole cells one at a time (their output follows),
	@# beside them the emulator's protocol tests, which mostly wait on sockets (tests/real/real_cell.py).
	@cells_log=$$(mktemp); \
	$(PY) -m pytest -m "realtime and cell" > $$cells_log 2>&1 & cells=$$!; \
	$(PY) -m pytest -m "realtime and not cell"; protocol=$$?; \
	wait $$cells; cells_rc=$$?; cat $$cells_log; rm -f $$cells_log; \
	test $$protocol -eq 0 && test $$cells_rc -eq 0

test: lint type pytest

# Mutation testing of the modules behind the published numbers (docs/testing.md); not part of `make test`.
# Configuration: [tool.mutmut] in pyproject.toml. Writes score.txt, stats.json, survivors.txt, survivors.diff.
MUTATION_OUT      ?= results/mutation
MUTATION_CHILDREN ?= 2
mutation: $(STAMP)
	rm -rf mutants
	$(VENV)/bin/mutmut run --max-children $(MUTATION_CHILDREN)
	mkdir -p $(MUTATION_OUT)
	$(VENV)/bin/mutmut export-cicd-stats
	cp mutants/mutmut-cicd-stats.json $(MUTATION_OUT)/stats.json
	$(VENV)/bin/mutmut results > $(MUTATION_OUT)/survivors.txt
	for m in $$(sed -n 's/^ *\([^ :]*\): .*/\1/p' $(MUTATION_OUT)/survivors.txt); do $(VENV)/bin/mutmut show $$m; done > $(MUTATION_OUT)/survivors.diff
	$(PY) -c "import json, sys; s = json.load(open(sys.argv[1])); n = s['total'] - s['skipped']; k = s['killed'] + s['timeout']; \
	print(f'mutation score {k}/{n} = {100 * k / max(n, 1):.1f} % (killed or timed out; survived {s[\"survived\"]}, no tests {s[\"no_tests\"]}, suspicious {s[\"suspicious\"]})')" \
	$(MUTATION_OUT)/stats.json | tee $(MUTATION_OUT)/score.txt

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache results mutants
