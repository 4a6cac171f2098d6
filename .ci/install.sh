# Sourced by .ci/setup and .ci/frameworks.sh.
# pip_install VENV ARGS...: install ARGS into VENV with uv (`uv pip install`), reading the
# indexes, find-links, constraints and certificate pip is configured with on this machine, so
# the same releases come from the same places as with pip, several times faster (a fresh
# `.[dev,ray]`: 27 s against 153 s). Where uv cannot be installed or fails, pip does it.
# GLMAP_SETUP_PIP=1 always uses pip.

# pip_setting VENV KEY: the value pip reads for KEY (its environment variable first, then the
# configuration files), empty when unset.
pip_setting() {
  "$1/bin/pip" config list 2>/dev/null | sed -n "s/^[^.]*\.$2='\(.*\)'\$/\1/p" | head -1
}

pip_install() {
  local venv="$1"
  shift
  if [ "${GLMAP_SETUP_PIP:-0}" != 1 ] && "$venv/bin/pip" install -q --disable-pip-version-check uv >/dev/null 2>&1; then
    local args=(--python "$venv/bin/python" --index-strategy unsafe-best-match) v
    # uv writes no .pyc files at install (pip does); Python writes each on first import, unless
    # PYTHONDONTWRITEBYTECODE is set: then every process would compile its imports anew.
    if [ -n "${PYTHONDONTWRITEBYTECODE:-}" ]; then args+=(--compile-bytecode); fi
    for v in $(pip_setting "$venv" index-url); do args+=(--index-url "$v"); done
    for v in $(pip_setting "$venv" extra-index-url); do args+=(--extra-index-url "$v"); done
    for v in $(pip_setting "$venv" find-links); do args+=(--find-links "$v"); done
    for v in $(pip_setting "$venv" constraint); do args+=(--constraint "$v"); done
    local cert envs=()
    cert="$(pip_setting "$venv" cert)"
    if [ -n "$cert" ]; then envs=("SSL_CERT_FILE=$cert"); fi
    if env "${envs[@]}" "$venv/bin/uv" pip install -q "${args[@]}" "$@"; then
      return 0
    fi
    echo "setup: uv could not install $*; pip does it" >&2
  fi
  # pip -q still prints one line per package for the machine's extra local indexes: drop them.
  "$venv/bin/pip" install -q --disable-pip-version-check "$@" 2>&1 |
    { grep -vE "is ignored: it is neither|does not provide the extra" || true; }
  return "${PIPESTATUS[0]}"
}
