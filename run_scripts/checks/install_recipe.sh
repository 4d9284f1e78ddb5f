#!/usr/bin/env bash
# Run docs/install.md's cluster recipe literally, against a PETSc that stands in for a module.
#
#   PETSC_DIR=/path/to/petsc [PETSC_ARCH=arch] [HDF5_DIR=/path/to/parallel/hdf5] \
#       bash run_scripts/checks/install_recipe.sh [SCRATCH]
#
# The fenced block after the marker "recipe: module-petsc" in docs/install.md is run with
# bash -euo pipefail as it stands: `module` is a no-op, $HOME is a scratch directory (default
# a new temporary one) holding a link to this repository as $HOME/contactpetsc.  PETSC_DIR
# may be the PETSc of run_scripts/setup_petsc_stack.sh:
#   $(~/.cache/contactpetsc/petsc-3.26.1-int64/bin/python -c 'import petsc; print(petsc.get_petsc_dir())')
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
: "${PETSC_DIR:?set PETSC_DIR to the PETSc standing in for the module}"
if [ -z "${HDF5_DIR:-}" ] && [ -d /usr/lib/x86_64-linux-gnu/hdf5/openmpi ]; then
    export HDF5_DIR=/usr/lib/x86_64-linux-gnu/hdf5/openmpi    # Debian's parallel HDF5
fi
scratch="${1:-$(mktemp -d /tmp/contactpetsc-recipe-XXXXXX)}"
mkdir -p "$scratch"
ln -sfn "$here" "$scratch/contactpetsc"
recipe="$scratch/recipe.sh"
awk '/<!-- recipe: module-petsc/ {found = 1; next}
     found && /^```bash/ {inside = 1; next}
     inside && /^```/ {exit}
     inside {print}' "$here/docs/install.md" > "$recipe"
[ -s "$recipe" ] || { echo "no recipe block found in docs/install.md" >&2; exit 2; }
echo "install_recipe: running docs/install.md's recipe ($(wc -l < "$recipe") lines) with HOME=$scratch"
export HOME="$scratch" PETSC_DIR HDF5_DIR
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
t0=$(date +%s)
bash -euo pipefail -c "module() { :; }; source '$recipe'"
echo "install_recipe: the recipe ran to the end in $(( $(date +%s) - t0 )) s; venv $scratch/venvs/contactpetsc"
