# murk: `make demo` and `make test` work on a fresh machine with nothing but Python 3.10+.
# torch is installed first so that pip does not pull a multi-GB CUDA build where a CPU one is wanted:
#   make test TORCH_INDEX=https://download.pytorch.org/whl/cpu      (official CPU wheels)
#   make test TORCH_INDEX=https://download.pytorch.org/whl/cu128    (CUDA 12.8 wheels)
PYTHON ?= python3
VENV ?= .venv
TORCH_SPEC ?= torch==2.13.0
TORCH_INDEX ?=
EXTRAS ?= dev,onnx,video,ros,webdataset,foxglove
PY := $(VENV)/bin/python
STAMP := $(VENV)/.murk-installed
PYTEST_ARGS ?= -n auto

.PHONY: demo test test-slow soak-test browser-test check lint typecheck layers bench install clean gpu-suite gpu-suite-dry-run gpu-deps \
	wheel-check

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q "$(TORCH_SPEC)" $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PY) -m pip install -q -e ".[$(EXTRAS)]"
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/murk demo --out murk-demo

# CI (.ci/run) runs `make test`: the house checks first, then the suite.
test: check
	$(PY) -m pytest -q $(PYTEST_ARGS)

# The house checks: lint + format, types against the committed baseline (may only shrink), import layering.
check: lint typecheck layers

typecheck: $(STAMP)
	$(PY) tools/mypy_baseline.py

layers: $(STAMP)
	$(VENV)/bin/lint-imports

# murk as users install it (CI runs it after make test, .ci/run): build the sdist and the wheel (no deprecation
# warning), install the wheel in a fresh virtual environment outside the checkout (not editable; its dependencies,
# torch included, reused from $(VENV), offline), then run murk --version, murk enhance and murk live from there.
wheel-check: $(STAMP)
	$(PY) tools/check_wheel.py

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow $(PYTEST_ARGS)

# murk live under a short soak and abuse run (benchmarks/soak_live.py, about 3 minutes; the long run: --minutes 15)
soak-test: $(STAMP)
	$(PY) -m pytest -q -m soak

browser-test: $(STAMP)
	command -v chromium >/dev/null || (apt-get update -qq && apt-get install -y -qq chromium)
	$(PY) -m pytest -q -m browser $(PYTEST_ARGS)

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests testkit benchmarks tools
	$(VENV)/bin/ruff format --check src tests testkit benchmarks tools

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

# On the GPU machine (no venv, no package registry): every GPU figure in at most 8 minutes (BENCHMARKS.md,
# "Measuring on a GPU"). Runs murk from the source tree with the system python3; gpu-deps/ (make gpu-deps) adds pytest.
GPU_SUITE_OUT ?= gpu-suite
gpu-suite:
	PYTHONPATH=$(CURDIR)/src$(if $(wildcard gpu-deps),:$(CURDIR)/gpu-deps)$${PYTHONPATH:+:$$PYTHONPATH} \
		$(PYTHON) benchmarks/gpu_suite.py --out $(GPU_SUITE_OUT) $(GPU_SUITE_ARGS)

# The same parts on the CPU at tiny sizes (CI runs it too: tests/benchmarks/test_gpu_suite.py).
gpu-suite-dry-run: $(STAMP)
	$(PY) benchmarks/gpu_suite.py --cpu-dry-run --out gpu-suite-dry-run

# pytest for the GPU machine (pure Python, carried there with the run tool's carry: ["gpu-deps"]).
gpu-deps: $(STAMP)
	$(PY) -m pip install -q --target gpu-deps --no-deps --only-binary=:all: --implementation py --abi none \
		--platform any pytest pluggy iniconfig packaging pygments exceptiongroup tomli

clean:
	rm -rf $(VENV) build dist src/*.egg-info .pytest_cache .ruff_cache .mypy_cache
