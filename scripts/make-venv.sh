#!/bin/sh
# Create the project's virtual environment; on Debian without python3-venv, install it first.
set -e
PYTHON="$1"
VENV="$2"
if ! "$PYTHON" -m venv "$VENV" 2>/dev/null; then
    rm -rf "$VENV"
    if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
        apt-get update -q >/dev/null && apt-get install -y -q python3-venv >/dev/null
        "$PYTHON" -m venv "$VENV"
    else
        echo "error: '$PYTHON -m venv' failed; install Python >= 3.11 with venv (Debian: python3-venv)" >&2
        exit 2
    fi
fi
