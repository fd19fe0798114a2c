# Pushbroom — developer entry points. `make setup` is idempotent.
SHELL := /bin/bash
PY := .venv/bin/python
APT_PACKAGES := qgis python3-qgis qgis-providers python3-gdal gdal-bin python3-scipy \
                python3-matplotlib python3-numpy python3-venv python3-pip xvfb zip \
                python3-dask python3-distributed python3-rasterio python3-xarray python3-skimage pyqt5-dev-tools \
                python3-tqdm python3-yaml python3-psutil python3-argcomplete
# the test and lint pins equal pyproject.toml's extras (tests/test_packaging.py checks it)
PIP_PINS := numba==0.60.0 llvmlite==0.43.0 pytest==8.3.3 pytest-qt==4.4.0 pytest-qgis==2.1.0 \
            hypothesis==6.112.2 pytest-xdist==3.6.1 laspy==2.5.4 lazrs==0.8.2 libsgm==0.5.2 ruff==0.17.6 mypy==1.13.0
# CNES pandora, the dense matcher's reference in one test (tests/algorithms/dense/test_sgm_pandora.py), in its own
# folder that only that test puts on sys.path: json-checker's and pandora-plugin-libsgm's wheels install a top-level
# `tests` package, which in the venv would shadow ours in QGIS's processes. Without its dependencies, which come
# from Debian (rasterio, xarray, scikit-image: built on the system GDAL and numpy; rasterio's wheel would bring a
# second GDAL).
PANDORA_PINS := pandora==1.9.0 pandora-plugin-libsgm==1.5.8 json-checker==2.0.0 transitions==0.9.3
# CNES Bulldozer, pushbroom:extractdtm's DSM-to-DTM (algorithms/products/extract_dtm.py), into the venv without its
# dependencies, which come from Debian (rasterio on the system GDAL, scikit-image, scipy, numpy 1.24, PyYAML, tqdm,
# psutil, argcomplete). 1.2.0: 1.3's code takes numpy 2 (np.bool) and its wheel installs a top-level `tests` package.
BULLDOZER_PIN := bulldozer-dtm==1.2.0
PANDORA_DIR := build/pandora
# metadata.txt holds the one version; pyproject.toml reads it through pushbroom.__version__
VERSION := $(shell sed -n 's/^version=//p' metadata.txt)
PROFILE := $(CURDIR)/build/qgis-profile
# qgis_process embeds the system Python: give it the venv's packages (numba) and a profile with the plugin
# (recursive variables: the venv exists only once setup has run)
SITE = $(wildcard $(CURDIR)/.venv/lib/python3*/site-packages)
# QGIS's Python start-up warns that sip's setapi() is deprecated, on every run: not ours, not a failure.
# OpenBLAS preloaded: qgis_process links GSL's reference CBLAS first, which numpy's matrix products would run
# (docs/architecture.md, "Same bits")
OPENBLAS := $(firstword $(realpath $(wildcard /usr/lib/*-linux-gnu/libblas.so.3)))
QGIS_PROCESS = env QGIS_CUSTOM_CONFIG_PATH=$(PROFILE) PYTHONPATH=$(SITE) PYTHONWARNINGS=ignore:setapi:DeprecationWarning \
	LD_PRELOAD=$(OPENBLAS) /usr/bin/qgis_process.bin
export QT_QPA_PLATFORM ?= offscreen
# Qt's run-time folder: without one, every Qt program (qgis_process, the tests' QGIS) says "XDG_RUNTIME_DIR not
# set"; a private one, made as Qt wants it (mode 0700)
RUNTIME := $(CURDIR)/build/xdg-runtime
export XDG_RUNTIME_DIR ?= $(RUNTIME)
export PIP_DISABLE_PIP_VERSION_CHECK := 1

# The texts to translate, extracted by pylupdate5 (Debian's pyqt5-dev-tools) from `translate("Pushbroom", "...")` and
# QT_TRANSLATE_NOOP("Pushbroom", "...") in the Processing glue; tests/plugin/test_translations.py checks that every
# label the dialogs show is in it. Translators copy it to i18n/pushbroom_<locale>.ts; `lrelease` makes the .qm that
# the plugin loads for QGIS's locale (plugin/plugin.py).
TS_FILE := i18n/pushbroom.ts
TRANSLATED := $(sort $(wildcard plugin/*.py plugin/algorithms/*.py))

.PHONY: setup lint test test-fast demo bench bench-peers bench-xdem package clean

setup: $(RUNTIME) .venv/.setup-done $(PROFILE)/.enabled $(PANDORA_DIR)/.done $(TS_FILE)

$(TS_FILE): $(TRANSLATED) .venv/.setup-done
	@mkdir -p i18n && PYTHONWARNINGS=ignore pylupdate5 -noobsolete $(TRANSLATED) -ts $@

$(RUNTIME):
	@mkdir -p -m 700 $@

$(PANDORA_DIR)/.done: .venv/.setup-done Makefile
	@rm -rf $(PANDORA_DIR) && $(PY) -m pip install -q --no-deps --target $(PANDORA_DIR) $(PANDORA_PINS)
	@PYTHONPATH=$(PANDORA_DIR) $(PY) -c "import pandora, rasterio; assert rasterio.__file__.startswith('/usr/lib/python3/'), rasterio.__file__"
	@touch $@

$(PROFILE)/.enabled: .venv/.setup-done metadata.txt | $(RUNTIME)
	@mkdir -p $(PROFILE)/profiles/default/python/plugins
	@ln -sfn $(CURDIR) $(PROFILE)/profiles/default/python/plugins/pushbroom
	@$(QGIS_PROCESS) plugins enable pushbroom >/dev/null 2>&1 || true  # exits 1 when already enabled
	@$(QGIS_PROCESS) list 2>/dev/null | grep -q 'pushbroom:createblock' || { echo "qgis_process does not list the Pushbroom provider"; exit 1; }
	@touch $@

.venv/.setup-done: pyproject.toml Makefile
	@missing=$$(for p in $(APT_PACKAGES); do dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "apt: installing $$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi
	@[ -x $(PY) ] || /usr/bin/python3 -m venv --system-site-packages .venv
	@$(PY) -m pip install -q $(PIP_PINS) "numpy==$$(/usr/bin/python3 -c 'import numpy; print(numpy.__version__)')"
	@$(PY) -m pip install -q --no-deps --no-build-isolation -e .
	@$(PY) -m pip install -q --no-deps $(BULLDOZER_PIN)
	@$(PY) -c "import numpy, numba, qgis.core, osgeo.gdal, distributed, c_libsgm, lazrs; assert numpy.__version__.startswith('1.'), numpy.__version__"
	@$(PY) -c "import rasterio, bulldozer.pipeline.bulldozer_pipeline; assert rasterio.__file__.startswith('/usr/lib/python3/'), rasterio.__file__"
	@touch $@

# The packages mypy checks, every function annotated (pyproject.toml, [tool.mypy]); more as they are touched.
MYPY_PACKAGES := algorithms.sensors algorithms.block algorithms.steps algorithms.execution algorithms.task_runtime \
                 algorithms.dask_backend algorithms.height_range algorithms.matching.strategy \
                 algorithms.matching.tiled_rounds algorithms.matching.stereo_set algorithms.matching.match_stats \
                 algorithms.dense.params algorithms.dense.refine algorithms.dense.epipolar algorithms.dense.precision \
                 algorithms.dense.dense_strategy algorithms.surface.cell_dem algorithms.quality.coregistration \
                 algorithms.quality.coregister_dem algorithms.surface.ept algorithms.surface.point_colour \
                 algorithms.products.merge_dems algorithms.products.extract_dtm algorithms.ortho.orthorectify

# ruff's linter and formatter, and mypy (configured in pyproject.toml); CI runs them before the tests.
lint: setup
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .
	MYPYPATH=$(PROFILE)/profiles/default/python/plugins .venv/bin/mypy $(addprefix -p pushbroom.,$(MYPY_PACKAGES))

# The whole suite, slow end-to-end tests included (CI runs this), on two pytest-xdist workers: a file's tests in
# one, the real-data tests together (tests/conftest.py); pytest-xdist hands out the largest groups first. A worker
# that crashes ends the run, naming the test it crashed in: pytest-xdist 3.6 to 3.8 can wait for ever after
# replacing a crashed worker under --dist loadgroup (pytest-xdist issues 1323, 1327, 1378).
# Two pytest workers on the 2 cores: each with one OpenBLAS thread, and numba's OpenMP threads sleeping when idle
# (their busy-waiting would take the other worker's core; the results are the same to the bit, golden tests included)
test: setup
	OPENBLAS_NUM_THREADS=1 OMP_WAIT_POLICY=passive $(PY) -m pytest -q -n 2 --dist loadgroup --max-worker-restart=0 --durations=15 tests

# Without the slow end-to-end tests, for quick iterations.
test-fast: setup
	$(PY) -m pytest -q -m "not slow" tests

# The main job on the built-in sample: simulate the SPOT-5 triplet over the Jacksboro DEM, then run the
# whole chain (resources/models/pushbroom_pipeline.model3: block, matching, adjustment, point cloud, DEM,
# orthoimage, accuracy report) through qgis_process like a user's script would; a styled QGIS project.
demo: setup
	@QGIS_PROCESS="$(QGIS_PROCESS)" bash scripts/demo.sh demo-output

# Benchmarks: writes bench-output/benchmarks.md and prints it.
bench: setup
	$(PY) -m tests.benchmarks.run_all bench-output/benchmarks.md

# The peers (not in CI): CNES CARS 1.3.0 in its own venv (it needs numpy 2; never in .venv), then Pushbroom's
# dense chain and CARS on the Pleiades triplet in one run; writes bench-output/peers.md and prints it.
CARS_VENV := build/peers/cars
$(CARS_VENV)/.done: Makefile
	@rm -rf $(CARS_VENV) && /usr/bin/python3 -m venv $(CARS_VENV) && $(CARS_VENV)/bin/pip install -q cars==1.3.0
	@touch $@

bench-peers: setup $(CARS_VENV)/.done
	@mkdir -p bench-output && $(PY) -m scripts.bench_peers | tee bench-output/peers.md

# Co-registration against xdem's NuthKaab (not in CI): xdem 0.2.3 in its own venv (its pyogrio and rasterio wheels
# bring GDALs of their own, never in .venv); writes bench-output/coregistration-peers.md and prints it.
XDEM_VENV := build/peers/xdem
$(XDEM_VENV)/.done: Makefile
	@rm -rf $(XDEM_VENV) && /usr/bin/python3 -m venv $(XDEM_VENV) && $(XDEM_VENV)/bin/pip install -q xdem==0.2.3
	@touch $@

bench-xdem: setup $(XDEM_VENV)/.done
	@mkdir -p bench-output && $(PY) -m scripts.coregistration_peers | tee bench-output/coregistration-peers.md

# The plugin zip for "Install from ZIP" in QGIS (tests and development files left out).
package:
	@rm -rf build/package && mkdir -p build/package/pushbroom dist
	@cp -r metadata.txt __init__.py version.py resource_files.py LICENSE README.md algorithms plugin ui resources docs i18n build/package/pushbroom/
	@find build/package -name __pycache__ -prune -exec rm -rf {} + ; find build/package -name '*.nb[ic]' -delete
	@rm -f dist/pushbroom-$(VERSION).zip && cd build/package && zip -qr ../../dist/pushbroom-$(VERSION).zip pushbroom
	@echo "dist/pushbroom-$(VERSION).zip"

clean:
	rm -rf build dist demo-output bench-output .venv
