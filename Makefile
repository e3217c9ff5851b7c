# The course's commands.  Everything installs itself: on a fresh machine `make course` and
# `make test` create .venv, install the pinned packages and generate the data first.
#
#   make course      execute every notebook (COURSE_MODE=class unless given), build the site in site/ (Sphinx; offline);
#                    each lesson's run time goes to results/lesson_times.json (the headers' times use the class-mode ones)
#   make site        build the site in site/ from the committed notebooks (executed in CI mode), no execution;
#                    both also build the browser demo in site/demo/ (make demo: web/, npm packages pinned)
#   make serve       serve site/ at http://localhost:8000 (a local static server)
#   make test        ruff + pytest (unit, property, rendering) + nbval on the committed notebooks (COURSE_MODE=ci)
#   make test-slow   the slow tests (a lone clone, Blender, the site in chromium, every exercise); .ci/run runs both
#   make setup       .venv with course_lib editable and the [dev] extras (fast when already done)
#   make data        the synthetic datasets in data/ (kept once made; `rm -r data` to regenerate)
#   make student     student copies (exercises without solutions, nbgrader) in student/, then JupyterLab there
#   make student-copies  only write the student copies into student/ (keeps existing ones; FORCE=1 rewrites)
#   make reproduce   retrain every checkpoint with the command in checkpoints/MANIFEST.json (COURSE_MODE=full)
#   make bench       timings table (python -m course_lib.timings)
#   make clean       remove site/, build/ and caches, never student/ (make distclean also removes .venv and data/)

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.stamp
COURSE_MODE ?= class
NOTEBOOKS := $(sort $(wildcard notebooks/[0-9]*.ipynb))
DATA := data/locomotion.npz data/actions.npz data/locomotion_noisy.npz

# Headless rendering (EGL, no X server); see README "Headless rendering".  MPLBACKEND=Agg is for
# the unit tests only: in a notebook kernel it would replace the inline backend and drop every figure.
HEADLESS := VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow PYVISTA_OFF_SCREEN=true PYVISTA_JUPYTER_BACKEND=static

.PHONY: help setup data course site demo serve test test-slow lint unit nbval reproduce student student-copies bench clean distclean delete-student-answers

help:
	@sed -n '4,18p' Makefile | sed 's/^# \{0,1\}//'

# ---- environment -------------------------------------------------------------------------------
setup: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@echo "setup: pip install -e \".[dev]\" into $(VENV) (a few minutes the first time)"
	@# this machine's pip config names local index folders that may be absent: drop those warnings
	$(PY) -m pip install --quiet -e ".[dev]" 2>&1 | { grep -v "is neither a file nor a directory" || true; }
	@touch $@
	@echo "setup: $(VENV) ready ($$($(PY) --version))"

# ---- data --------------------------------------------------------------------------------------
# The scripts refuse to overwrite their outputs, so each output file is a target: made once, kept.
data: $(DATA)

data/locomotion.npz: | $(STAMP)
	$(PY) data_scripts/make_locomotion.py --out $@

data/actions.npz: | $(STAMP)
	$(PY) data_scripts/make_actions.py --out $@

data/locomotion_noisy.npz: data/locomotion.npz | $(STAMP)
	$(PY) data_scripts/make_noisy.py --input $< --out $@

# ---- the course --------------------------------------------------------------------------------
# Executes copies of the notebooks (the committed ones are never overwritten) into build/executed/,
# then builds the site from them (tools/build_site.py: Sphinx + MyST-NB + the book theme, MathJax served
# from site/_static: works offline).  `make site` builds it from the committed notebooks (executed in
# CI mode) without executing anything.
course: setup data
	@mkdir -p build/executed; failed=""; rm -f build/executed/*.ipynb; \
	for nb in $(NOTEBOOKS); do \
	  start=$$(date +%s); echo "course: $$nb (COURSE_MODE=$(COURSE_MODE))"; \
	  if env -u MPLBACKEND COURSE_MODE=$(COURSE_MODE) TQDM_DISABLE=1 $(HEADLESS) $(VENV)/bin/jupyter nbconvert \
	       --to notebook --execute --ExecutePreprocessor.timeout=1800 --output-dir build/executed "$$nb"; then \
	    secs=$$(( $$(date +%s) - start )); echo "course: $$nb done in $$secs s"; \
	    $(PY) tools/lesson_time.py --record "$$nb" "$$secs" --mode $(COURSE_MODE); \
	  else failed="$$failed $$nb"; rm -f "build/executed/$$(basename "$$nb")"; fi; \
	done; \
	$(PY) tools/build_site.py --notebooks build/executed --site site --work build/site --mode $(COURSE_MODE) --demo; \
	if [ -n "$$failed" ]; then echo "course: FAILED (not in the site):$$failed" >&2; exit 1; fi
	@# its own line: make runs a line that names $(MAKE) even under `make -n`
	@$(MAKE) --no-print-directory demo

site: setup
	$(PY) tools/build_site.py --notebooks notebooks --site site --work build/site --mode ci --demo
	@$(MAKE) --no-print-directory demo

# The browser demo (web/, lesson 06): the pretrained MoGlow step as ONNX, bundled with onnxruntime-web and
# three.js into plain files in site/demo/ (opens from file:// and over a local server; nothing fetched).
demo: setup web/node_modules/.stamp
	$(PY) -m course_lib.export build/web-assets --force
	cd web && node build.mjs --assets ../build/web-assets --out ../site/demo
	@echo "demo: site/demo/index.html (add ?selftest=1 for the self-test)"

# the built site over a local static server (the demo page works from file:// too)
serve:
	@test -f site/index.html || { echo "serve: no site/ yet: run make site (or make course) first" >&2; exit 1; }
	$(PY) -m http.server --directory site 8000

web/node_modules/.stamp: web/package.json web/package-lock.json
	cd web && npm ci --no-audit --no-fund --loglevel=error
	@touch $@

# ---- tests -------------------------------------------------------------------------------------
test: lint unit nbval

lint: setup
	$(VENV)/bin/ruff check .

unit: setup
	@start=$$(date +%s); \
	echo "COURSE_MODE=ci $(PY) -m pytest -n 2 -m 'not slow' tests"; \
	COURSE_MODE=ci OMP_NUM_THREADS=1 MPLBACKEND=Agg $(HEADLESS) $(PY) -m pytest -n 2 -m "not slow" tests; \
	echo "unit: tests took $$(( $$(date +%s) - start )) s"

test-slow: setup web/node_modules/.stamp
	@start=$$(date +%s); \
	COURSE_MODE=ci OMP_NUM_THREADS=1 MPLBACKEND=Agg $(HEADLESS) $(PY) -m pytest -n 2 -m slow tests; \
	echo "test-slow: tests took $$(( $$(date +%s) - start )) s"

# nbval re-executes each committed notebook in the venv's kernel and compares the
# `# NBVAL_CHECK_OUTPUT` cells.  With no notebooks yet there is nothing to run (pytest would exit 5).
nbval: setup
	@if [ -z "$(NOTEBOOKS)" ]; then echo "nbval: no notebooks in notebooks/ yet"; else \
	  start=$$(date +%s); echo "COURSE_MODE=ci $(PY) -m pytest --nbval-lax $(NOTEBOOKS)"; \
	  env -u MPLBACKEND COURSE_MODE=ci TQDM_DISABLE=1 OMP_NUM_THREADS=1 $(HEADLESS) $(PY) -m pytest -p no:xdist \
	    --nbval-lax --nbval-current-env --nbval-cell-timeout=300 $(NOTEBOOKS); \
	  echo "nbval: notebooks took $$(( $$(date +%s) - start )) s"; fi

# ---- the rest ----------------------------------------------------------------------------------
reproduce: setup data
	COURSE_MODE=full $(HEADLESS) $(PY) tools/reproduce.py --manifest checkpoints/MANIFEST.json

# nbgrader's preprocessors remove the solutions (tools/student_copies.py); the release notebooks stay as they are.
student-copies: setup
	$(PY) tools/student_copies.py --notebooks notebooks --out student $(if $(FORCE),--force)

student: student-copies data
	$(VENV)/bin/jupyter lab student/

bench: setup
	$(PY) -m course_lib.timings

# `clean` never touches student/ (your answers); `delete-student-answers` does, and says so.
clean:
	rm -rf site build .pytest_cache .ruff_cache .hypothesis
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +
	find notebooks -name .ipynb_checkpoints -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) data *.egg-info web/node_modules

delete-student-answers:
	@echo "delete-student-answers: removing student/ and every answer in it"
	rm -rf student
