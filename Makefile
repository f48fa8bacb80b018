# Two commands on a fresh clone: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
STAMP  := $(VENV)/.installed
DEMO_WORKSPACE ?= runs/demo
export OMP_NUM_THREADS ?= 1

.PHONY: install demo readme test lint docs bench clean

$(PY):
	$(PYTHON) -m venv $(VENV)

# torch first (a local CPU wheel), then the project under a constraint that keeps that torch.
$(STAMP): $(PY) pyproject.toml constraints.txt
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet torch==2.13.0
	$(PIP) install --quiet -c constraints.txt -e '.[test,docs]'
	touch $(STAMP)

install: $(STAMP)

# `rapomdp demo` (what pip users run): the dataset, its contact sheet, every stage, Table 1
# and the summary (report path, who won, wall time, memory); W/report/report.html.
# Two PyTorch threads for the serial stages (train, crossfit, observe): the training throughput
# against one thread is in benchmarks/results/classifier_speed.txt; the parallel stages use two
# single-threaded processes whatever this says.
DEMO_THREADS ?= 2
demo: $(STAMP)
	$(VENV)/bin/rapomdp demo --workspace $(DEMO_WORKSPACE) --threads $(DEMO_THREADS)

# The README's generated results block (and docs/figures/demo_*.png) from the demo workspace.
readme: demo
	$(VENV)/bin/rapomdp report --workspace $(DEMO_WORKSPACE) --readme README.md

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(PY) -m mypy
	OMP_NUM_THREADS=1 $(PY) -m pytest -q
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet

# The documentation site (mkdocs.yml), offline: site/index.html. Any warning is an error.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks

# Measured figures (minutes; not part of the tests). Outputs: benchmarks/results/.
bench: $(STAMP)
	$(PY) benchmarks/render_speed.py | tee benchmarks/results/render_speed.txt
	$(PY) benchmarks/robot_ik.py --placements | tee benchmarks/results/robot_ik.txt
	$(PY) benchmarks/planning_flat_benchmarks.py | tee benchmarks/results/planning_flat_benchmarks.txt
	$(PY) benchmarks/planning_active_recognition.py | tee benchmarks/results/planning_active_recognition.txt
	$(PY) benchmarks/planning_active_recognition.py --sizes 128x85 | tee benchmarks/results/planning_any_size.txt
	$(PY) benchmarks/planning_flat_limits.py | tee benchmarks/results/planning_flat_limits.txt
	$(PY) benchmarks/planning_startup.py | tee benchmarks/results/planning_startup.txt
	$(PY) benchmarks/classifier_speed.py | tee benchmarks/results/classifier_speed.txt
	$(PY) benchmarks/saliency_speed.py | tee benchmarks/results/saliency_speed.txt
	$(VENV)/bin/rapomdp run --workspace $(DEMO_WORKSPACE)
	$(PY) benchmarks/episode_loop.py --workspace $(DEMO_WORKSPACE)
	$(PY) benchmarks/vptree_baseline.py --workspace $(DEMO_WORKSPACE)
	$(PY) benchmarks/dataset_difficulty.py --workspace $(DEMO_WORKSPACE)

clean:
	rm -rf $(VENV) runs site
