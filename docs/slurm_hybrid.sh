#!/bin/bash
# Slurm job template for a coupled LAMMPS + MPM run (fix hybrid/mpm, docs/fix_hybrid_mpm.md).
# Copy it, adjust the #SBATCH lines and the variables below, submit with `sbatch slurm_hybrid.sh`.
#
# The job is one MPI_COMM_WORLD holding NLAMMPS LAMMPS ranks and one mpm_solver rank. The
# programs find each other by the colour they split MPI_COMM_WORLD with, not by their order,
# so both launch forms below work. mpm_solver will later use OpenMP threads: give its task
# the cores (MPM_THREADS) and keep NLAMMPS + MPM_THREADS within the allocation.
#
#SBATCH --job-name=hybrid-granular
#SBATCH --nodes=1
#SBATCH --ntasks=5                 # NLAMMPS + 1
#SBATCH --cpus-per-task=1
#SBATCH --time=01:00:00
#SBATCH --output=%x-%j.out

set -euo pipefail

REPO=${REPO:-$HOME/hybrid-granular}           # the project checkout (built with tools/setup.sh)
DECK=${DECK:-$REPO/input_decks/hybrid/handshake.lmp}
NLAMMPS=$((SLURM_NTASKS - 1))
MPM_THREADS=${MPM_THREADS:-1}
LMP=$REPO/build/lammps_fix_hybrid/lmp_hybrid
MPM=$REPO/build/mpm_solver/mpm_solver

cd "${SLURM_SUBMIT_DIR:-$PWD}"

# ---- Form 1: srun --multi-prog (Slurm starts the tasks; needs Open MPI with PMIx support,
# as Debian's has: --mpi=pmix).
conf=$(mktemp "hybrid-multiprog.XXXXXX.conf")
trap 'rm -f "$conf"' EXIT
cat > "$conf" <<EOF
0-$((NLAMMPS - 1)) $LMP -in $DECK -log log.lammps
$NLAMMPS env OMP_NUM_THREADS=$MPM_THREADS $MPM --coupled
EOF
srun --mpi=pmix --kill-on-bad-exit=1 --multi-prog "$conf"

# ---- Form 2: mpirun inside the allocation (Open MPI reads the Slurm allocation itself).
# Instead of the srun line above:
#   mpirun -np "$NLAMMPS" "$LMP" -in "$DECK" -log log.lammps \
#        : -np 1 -x OMP_NUM_THREADS="$MPM_THREADS" "$MPM" --coupled
# or, from the checkout, the same through the project's launcher:
#   "$REPO/tools/hybrid_launch.py" -np "$NLAMMPS" "$DECK" -log log.lammps
#
# With a PLUGIN-enabled LAMMPS instead of lmp_hybrid, start it as `lmp -m 0 -in wrapper.lmp`
# where wrapper.lmp holds `plugin load .../hybridmpmplugin.so` and `include <deck>`
# (tools/hybrid_launch.py --plugin does this).
