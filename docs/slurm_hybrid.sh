#!/bin/bash
# Slurm job template for a coupled DEM + MPM run (fix hybrid/mpm, docs/fix_hybrid_mpm.md), with
# either DEM host:
#   HOST=lammps   (default) lmp_hybrid, LAMMPS with the fix; decks *.lmp, 2D or 3D
#   HOST=liggghts liggghts_hybrid, LIGGGHTS 3.8 with the fix; decks *.liggghts, 3D only
#                 (docs/fix_hybrid_mpm.md, "LIGGGHTS host")
# Copy it, adjust the #SBATCH lines and the variables below, submit with `sbatch slurm_hybrid.sh`,
# e.g. `HOST=liggghts DECK=$PWD/deck.liggghts sbatch slurm_hybrid.sh` (sbatch passes the
# environment on).
#
# The job is one MPI_COMM_WORLD holding NDEM DEM ranks and one mpm_solver rank. The
# programs find each other by the colour they split MPI_COMM_WORLD with, not by their order,
# so both launch forms below work. mpm_solver will later use OpenMP threads: give its task
# the cores (MPM_THREADS) and keep NDEM + MPM_THREADS within the allocation.
#
#SBATCH --job-name=hybrid-granular
#SBATCH --nodes=1
#SBATCH --ntasks=5                 # NLAMMPS + 1
#SBATCH --cpus-per-task=1
#SBATCH --time=01:00:00
#SBATCH --output=%x-%j.out

set -euo pipefail

REPO=${REPO:-$HOME/hybrid-granular}           # the project checkout (built with tools/setup.sh)
HOST=${HOST:-lammps}                           # the DEM host: lammps or liggghts
case "$HOST" in
  lammps)   DEM=$REPO/build/lammps_fix_hybrid/lmp_hybrid
            DECK=${DECK:-$REPO/input_decks/hybrid/handshake.lmp} ;;
  liggghts) DEM=$REPO/build/lammps_fix_hybrid/liggghts_hybrid
            DECK=${DECK:-$REPO/input_decks/hybrid/momentum_3d.liggghts} ;;
  *) echo "slurm_hybrid.sh: HOST=$HOST is not a DEM host of fix hybrid/mpm: use HOST=lammps or HOST=liggghts" >&2
     exit 2 ;;
esac
[ -x "$DEM" ] || { echo "slurm_hybrid.sh: $DEM is not built (tools/setup.sh in $REPO)" >&2; exit 2; }
NDEM=$((SLURM_NTASKS - 1))
MPM_THREADS=${MPM_THREADS:-1}
MPM=$REPO/build/mpm_solver/mpm_solver

cd "${SLURM_SUBMIT_DIR:-$PWD}"

# ---- Form 1: srun --multi-prog (Slurm starts the tasks; needs Open MPI with PMIx support,
# as Debian's has: --mpi=pmix).
conf=$(mktemp "hybrid-multiprog.XXXXXX.conf")
trap 'rm -f "$conf"' EXIT
cat > "$conf" <<EOF
0-$((NDEM - 1)) $DEM -in $DECK -log log.lammps
$NDEM env OMP_NUM_THREADS=$MPM_THREADS $MPM --coupled
EOF
srun --mpi=pmix --kill-on-bad-exit=1 --multi-prog "$conf"

# ---- Form 2: mpirun inside the allocation (Open MPI reads the Slurm allocation itself).
# Instead of the srun line above:
#   mpirun -np "$NDEM" "$DEM" -in "$DECK" -log log.lammps \
#        : -np 1 -x OMP_NUM_THREADS="$MPM_THREADS" "$MPM" --coupled
# or, from the checkout, the same through the project's launcher:
#   "$REPO/tools/hybrid_launch.py" --host "$HOST" -np "$NDEM" "$DECK" -log log.lammps
#
# With a PLUGIN-enabled LAMMPS instead of lmp_hybrid (HOST=lammps only), start it as
# `lmp -m 0 -in wrapper.lmp` where wrapper.lmp holds `plugin load .../hybridmpmplugin.so` and
# `include <deck>` (tools/hybrid_launch.py --plugin does this).
