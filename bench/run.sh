#!/usr/bin/env bash
# All benchmarks, one command. Each figure is printed with a baseline measured in the same run.
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python bench/frontend.py "$@"
