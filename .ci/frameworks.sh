#!/usr/bin/env bash
# Idempotent: a fresh venv per agent framework, under .ci/venvs/, as a new user makes one from
# docs/frameworks/ (LangChain's and smolagents' MCP adapters pin mcp 1.x, glmap-mcp needs mcp 2.x).
# tests/frameworks/ and tests/test_docs_run.py run their python as a subprocess that starts
# .venv/bin/glmap-mcp over stdio by its absolute path. Exact versions: the framework table in
# docs/frameworks/README.md is measured with them.
# A venv is rebuilt only when its requirement line changes (seconds each with uv).
set -euo pipefail
cd "$(dirname "$0")/.."
source .ci/install.sh  # pip_install: uv with pip's settings, pip where uv fails

build() {  # NAME REQUIREMENT...
  local dir=".ci/venvs/$1"
  shift
  if [ -x "$dir/bin/python" ] && [ "$(cat "$dir/requirements.txt" 2>/dev/null)" = "$*" ]; then
    return
  fi
  rm -rf "$dir"
  python3 -m venv "$dir"
  pip_install "$dir" "$@"
  echo "$*" >"$dir/requirements.txt"
}

build langchain langchain-mcp-adapters==0.3.2 langchain-core==1.8.3 mcp==1.30.0
build smolagents "smolagents[mcp]==1.26.0" mcpadapt==0.1.19 mcp==1.30.0
build pydantic-ai "pydantic-ai-slim[mcp]==2.68.0" fastmcp-slim==4.2.3 mcp==2.3.0
