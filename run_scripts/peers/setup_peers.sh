#!/usr/bin/env bash
# Create isolated venvs holding the peer contact codes used for side-by-side
# benchmarks (nothing here is vendored into contactpetsc).
#
#   peer venv     ${CONTACTPETSC_PEER_VENV:-$HOME/.cache/contactpetsc/peer-venv}
#                 -> tamaas + numpy (used by run_scripts/peers/tamaas_signorini.py)
#   peer venv cm  ${CONTACTPETSC_PEER_VENV}-cm
#                 -> ContactMechanics + Adhesion (contact.engineering; best effort;
#                    NuMPI comes with it; used by cm_adhesion.py and cm_signorini.py)
#
# Idempotent: a venv whose imports already succeed is left alone, so a second
# run takes a second or two.  The venvs are created WITHOUT system site
# packages so the wheels' numpy never clashes with Debian's python3-numpy.
#
# Usage: bash run_scripts/peers/setup_peers.sh [--no-cm]
#   --no-cm   skip the (optional) ContactMechanics/Adhesion venv
# Env:   CONTACTPETSC_PEER_VENV, CONTACTPETSC_PEER_PYTHON (interpreter override)
set -u

PEER_VENV="${CONTACTPETSC_PEER_VENV:-$HOME/.cache/contactpetsc/peer-venv}"
CM_VENV="${PEER_VENV}-cm"
DO_CM=1
for a in "$@"; do
  case "$a" in
    --no-cm) DO_CM=0 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "setup_peers: unknown argument $a" >&2; exit 2 ;;
  esac
done

log() { echo "[setup_peers] $*" >&2; }

# Pick a base interpreter that can make a venv with pip (needs venv+ensurepip).
pick_python() {
  local cands=()
  [ -n "${CONTACTPETSC_PEER_PYTHON:-}" ] && cands+=("$CONTACTPETSC_PEER_PYTHON")
  cands+=(/usr/bin/python3 python3 python3.11)
  local p
  for p in "${cands[@]}"; do
    command -v "$p" >/dev/null 2>&1 || continue
    if "$p" -c 'import sys, venv, ensurepip; assert sys.version_info >= (3, 9)' \
         >/dev/null 2>&1; then
      echo "$p"; return 0
    fi
  done
  return 1
}

# make_venv DIR "import check" pkg...   -> 0 on success
make_venv() {
  local dir="$1" check="$2"; shift 2
  if [ -x "$dir/bin/python" ] && "$dir/bin/python" -c "$check" >/dev/null 2>&1; then
    log "$dir: already set up ($("$dir/bin/python" -c "$check" 2>/dev/null | tail -1))"
    return 0
  fi
  local py
  py="$(pick_python)" || { log "no python3 with venv+ensurepip found"; return 1; }
  if [ ! -x "$dir/bin/python" ]; then
    log "creating venv $dir with $py ($("$py" --version 2>&1))"
    mkdir -p "$(dirname "$dir")"
    "$py" -m venv "$dir" || { log "venv creation failed"; rm -rf "$dir"; return 1; }
  fi
  "$dir/bin/python" -m pip install --disable-pip-version-check -q --upgrade pip \
    >/dev/null 2>&1 || true
  log "pip install $* into $dir"
  "$dir/bin/python" -m pip install --disable-pip-version-check "$@" || return 1
  "$dir/bin/python" -c "$check" || return 1
}

rc=0
t0=$(date +%s)
TAMAAS_CHECK='import numpy, tamaas; print("tamaas", tamaas.__version__, "numpy", numpy.__version__)'
if make_venv "$PEER_VENV" "$TAMAAS_CHECK" tamaas numpy; then
  log "tamaas venv OK: $PEER_VENV/bin/python"
else
  log "ERROR: could not set up the tamaas venv at $PEER_VENV"; rc=1
fi

if [ "$DO_CM" = 1 ]; then
  CM_CHECK='import ContactMechanics, Adhesion; print("ContactMechanics", ContactMechanics.__version__, "Adhesion", getattr(Adhesion, "__version__", "?"))'
  if make_venv "$CM_VENV" "$CM_CHECK" numpy ContactMechanics Adhesion; then
    log "ContactMechanics/Adhesion venv OK: $CM_VENV/bin/python"
  else
    # optional: report but do not fail the tamaas setup
    log "WARNING: ContactMechanics/Adhesion could not be installed in $CM_VENV (see pip output above)"
  fi
fi
log "done in $(( $(date +%s) - t0 )) s"
exit $rc
