# the lab's shared data (held-out maps, real photos): relight bench/dataset read $RELIGHT_DATA/hdri and /photos
export RELIGHT_DATA ?= $(abspath ../shared/data)

.PHONY: demo test bench setup

setup:
	bash scripts/setup.sh

demo: setup
	.venv/bin/relight demo

test: setup
	.venv/bin/ruff check .
	.venv/bin/python -m pytest -q tests -n auto --dist loadgroup --no-loadscope-reorder --durations=25

bench: setup
	.venv/bin/relight bench engine
