# Two commands do everything on a fresh machine (see README.md):
#   make demo   - builds the venv, generates the sample scene, culls it, benchmarks it
#   make test   - builds the venv and runs the whole test suite
PY ?= python3.11
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-v2

.PHONY: venv demo test test-numpy2 test-bpy42 lint extension clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(VPY) -m pip install -q --upgrade pip
	$(VPY) -m pip install -q -e '.[dev]' 'numpy>=1.26,<2' 'bpy==5.0.1'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VPY) -m core demo

# The engine's GL answers a second time on the OpenGL 4.1 path (what macOS gets;
# core/gl/context.py): the modules whose tests cull, render truths or read GL state.
GL41_TESTS := $(addprefix tests/,test_conservative_answers.py test_engine.py test_envelope.py \
	test_gl.py test_gl_layout.py test_gpu_strategy.py test_strategies.py test_fuzz_truth.py \
	test_lights.py test_repeatable_answers.py test_upload_dtypes.py)
test: $(STAMP)
	$(VPY) -m pytest -q
	OCC_GL=4.1 $(VPY) -m pytest -q -m "not blender and not gui" $(GL41_TESTS)

# Python 3.13 with numpy 2.x and Blender 5.2 (bpy from PyPI): the whole suite again,
# on the other numpy and the other Blender line the extension supports; not the window
# tests (tests/gui: Debian's Blender 3.4 with its own Python, the same run as make test's).
VENV2 := .venv-numpy2
$(VENV2)/.installed-v2: pyproject.toml
	PYENV_VERSION=3.13.0 python3.13 -m venv $(VENV2)
	$(VENV2)/bin/python -m pip install -q -e '.[dev]' 'numpy>=2.2' 'bpy>=5.2,<5.3'
	touch $@

test-numpy2: $(VENV2)/.installed-v2
	$(VENV2)/bin/python -m pytest -q -m "not gui"

# Blender 4.2 LTS (bpy 4.2 from PyPI, Python 3.11), the oldest line the manifest accepts:
# the tests inside Blender again (tests/blender), in their own venv.
VENV42 := .venv-bpy42
$(VENV42)/.installed-42: pyproject.toml
	$(PY) -m venv $(VENV42)
	$(VENV42)/bin/python -m pip install -q -e '.[dev]' 'numpy>=1.26,<2' 'bpy==4.2.0'
	touch $@

test-bpy42: $(VENV42)/.installed-42
	$(VENV42)/bin/python -m pytest -q tests/blender

# The type checker on the public seams (mypy, installed here on first use; not in CI's venvs).
TYPED := core/engine.py core/cull/ core/envelope.py core/gl/renderer.py occ_addon/session.py
lint: $(STAMP)
	$(VPY) -m ruff check core occ_addon tests tools sample_scenes
	$(VPY) -m mypy --version >/dev/null 2>&1 || $(VPY) -m pip install -q 'mypy==1.13.0'
	$(VPY) -m mypy $(TYPED)

# The extension zips into dist/, one per platform: needs only python3 with pip (no venv);
# built and validated by Blender's own CLI when $(BLENDER) or `blender` on PATH exists.
EXT_PY ?= python3
extension:
	$(EXT_PY) tools/build_extension.py $(if $(BLENDER),--blender $(BLENDER))

clean:
	rm -rf $(VENV) $(VENV2) dist build .cache
