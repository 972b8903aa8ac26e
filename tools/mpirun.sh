#!/usr/bin/env bash
# tools/mpirun.sh - mpirun (Open MPI) with this machine's quirks handled:
#   * as root, sets OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
#   * adds --oversubscribe when the requested ranks (all -np/-n values, summed
#     over MPMD app contexts separated by ':') exceed the available cores
# Everything else is passed through unchanged, e.g.
#   tools/mpirun.sh -np 2 lmp_hybrid -in deck.lmp : -np 1 build/mpm_solver/mpm_solver scene.toml
# Environment: HYBRID_MPIRUN (default mpirun), HYBRID_MPIRUN_VERBOSE=1 prints the command.
set -euo pipefail

MPIRUN="${HYBRID_MPIRUN:-mpirun}"
if ! command -v "$MPIRUN" >/dev/null 2>&1; then
  echo "mpirun.sh: ERROR: '$MPIRUN' not found (Debian package openmpi-bin; run tools/setup.sh)" >&2
  exit 127
fi

if [[ $(id -u) -eq 0 ]]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

# Cores Open MPI will count as slots: physical cores, limited by our CPU affinity.
slots=$(nproc)
if command -v lscpu >/dev/null 2>&1; then
  phys=$(lscpu -p=socket,core 2>/dev/null | grep -v '^#' | sort -u | wc -l || true)
  if [[ ${phys:-0} -gt 0 && $phys -lt $slots ]]; then slots=$phys; fi
fi

args=("$@")
n=${#args[@]}
total=0
oversub=0
in_program=0   # inside "executable args..." of an app context, until ':'
i=0
add_ranks() { [[ ${1:-} =~ ^[0-9]+$ ]] && total=$((total + 10#$1)) || true; }
while [[ $i -lt $n ]]; do
  a=${args[i]}
  if [[ $in_program -eq 1 ]]; then
    [[ $a == ":" ]] && in_program=0
    i=$((i + 1)); continue
  fi
  case $a in
    :) ;;
    -np|--np|-n|--n|-c)
      add_ranks "${args[i+1]:-}"; i=$((i + 1)) ;;
    -np=*|--np=*|-n=*|--n=*)
      add_ranks "${a#*=}" ;;
    -oversubscribe|--oversubscribe)
      oversub=1 ;;
    -map-by|--map-by)
      [[ ${args[i+1]:-} == *[Oo][Vv][Ee][Rr][Ss][Uu][Bb][Ss][Cc][Rr][Ii][Bb][Ee]* ]] && oversub=1
      i=$((i + 1)) ;;
    --map-by=*)
      [[ $a == *[Oo][Vv][Ee][Rr][Ss][Uu][Bb][Ss][Cc][Rr][Ii][Bb][Ee]* ]] && oversub=1 ;;
    -mca|--mca|-gmca|--gmca|-omca|--omca)
      i=$((i + 2)) ;;
    # options that take one value
    -H|-host|--host|-hostfile|--hostfile|-machinefile|--machinefile|--default-hostfile| \
    -x|-rank-by|--rank-by|-bind-to|--bind-to|-wdir|--wdir|-wd|--wd|-prefix|--prefix| \
    -output-filename|--output-filename|-npernode|--npernode|-N|-npersocket|--npersocket| \
    -ppr|--ppr|-cpus-per-proc|--cpus-per-proc|-cpus-per-rank|--cpus-per-rank| \
    -timeout|--timeout|-path|--path|-preload-files|--preload-files|-tune|--tune| \
    -am|--am|-app|--app|-rf|--rankfile|-report-uri|--report-uri| \
    -stdin|--stdin|-xml-file|--xml-file)
      i=$((i + 1)) ;;
    -*) ;;            # flags without a value
    *) in_program=1 ;; # the executable of this app context
  esac
  i=$((i + 1))
done

extra=()
if [[ $oversub -eq 0 && $total -gt $slots ]]; then
  extra=(--oversubscribe)
fi
if [[ ${HYBRID_MPIRUN_VERBOSE:-0} == 1 ]]; then
  echo "mpirun.sh: $total ranks, $slots cores: $MPIRUN ${extra[*]} $*" >&2
fi
exec "$MPIRUN" "${extra[@]}" "$@"
