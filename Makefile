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
# Two PyTorch threads for the serial stages (train, observe): the training throughput
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
	# tests/test_docs.py builds the documentation site with mkdocs build --strict
	OMP_NUM_THREADS=1 $(PY) -m pytest -q

# The documentation site (mkdocs.yml), offline: site/index.html. Any warning is an error.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks

# Every benchmark that needs nothing but this repository (about an hour on 2 cores; not part of
# the tests). The others, which need a study, a second source tree or a Debian package, are
# listed with their commands in benchmarks/README.md. Outputs: benchmarks/results/.
BENCH_W := $(DEMO_WORKSPACE)
bench: $(STAMP)
	$(PY) benchmarks/render_speed.py | tee benchmarks/results/render_speed.txt
	$(PY) benchmarks/robot_ik.py --placements | tee benchmarks/results/robot_ik.txt
	$(PY) benchmarks/planning_active_recognition.py | tee benchmarks/results/planning_active_recognition.txt
	$(PY) benchmarks/planning_active_recognition.py --sizes 128x85 | tee benchmarks/results/planning_any_size.txt
	$(PY) benchmarks/planning_flat_limits.py | tee benchmarks/results/planning_flat_limits.txt
	$(PY) benchmarks/planning_startup.py | tee benchmarks/results/planning_startup.txt
	$(PY) benchmarks/classifier_speed.py | tee benchmarks/results/classifier_speed.txt
	$(PY) benchmarks/inference_speed.py | tee benchmarks/results/inference_speed.txt
	$(PY) benchmarks/torch_variants.py | tee benchmarks/results/torch_variants.txt
	$(PY) benchmarks/saliency_speed.py | tee benchmarks/results/saliency_speed.txt
	$(PY) benchmarks/cli_help_startup.py | tee benchmarks/results/cli_help_startup.txt
	$(PY) benchmarks/package_graph.py | tee benchmarks/results/package_graph.txt
	$(PY) benchmarks/fault_table.py
	$(PY) benchmarks/artefact_hashes.py --compare benchmarks/results/artefact_hashes_main.json
	$(VENV)/bin/rapomdp run --workspace $(BENCH_W)
	$(PY) benchmarks/episode_loop.py --workspace $(BENCH_W)
	$(PY) benchmarks/vptree_baseline.py --workspace $(BENCH_W)
	$(PY) benchmarks/dataset_difficulty.py --workspace $(BENCH_W)
	$(PY) benchmarks/env_check.py $(BENCH_W) | tee benchmarks/results/env_check.txt
	$(PY) benchmarks/evidence_ceiling.py -w $(BENCH_W) | tee benchmarks/results/evidence_ceiling_demo.txt
	$(PY) benchmarks/ece_floor.py -w $(BENCH_W) | tee benchmarks/results/ece_floor_demo.txt
	$(PY) benchmarks/lookahead_speed.py -w $(BENCH_W) | tee benchmarks/results/lookahead_speed.txt
	$(PY) benchmarks/mask_convergence.py -w $(BENCH_W) | tee benchmarks/results/mask_convergence.txt
	$(PY) benchmarks/saliency_methods_quality.py -w $(BENCH_W) | tee benchmarks/results/saliency_methods_quality.txt
	$(PY) benchmarks/volume_observe_timing.py -w $(BENCH_W) | tee benchmarks/results/volume_observe.txt
	$(PY) benchmarks/ensemble_train_speed.py -w $(BENCH_W) | tee benchmarks/results/ensemble_train_speed.txt
	$(PY) benchmarks/ra_choice_transfer.py -w $(BENCH_W) | tee benchmarks/results/ra_choice_transfer_demo.txt
	$(PY) benchmarks/study_headroom.py -w $(BENCH_W) | tee benchmarks/results/headroom_demo.txt
	$(PY) benchmarks/demo_stage_times.py $(BENCH_W) | tee benchmarks/results/demo_stage_times.txt
	$(PY) benchmarks/dask_evaluate.py

clean:
	rm -rf $(VENV) runs site
