// lmp_hybrid: the stock LAMMPS main program (as LAMMPS's src/main.cpp) linked with
// Debian's liblammps, plus the fix style hybrid/mpm registered in the LAMMPS instance.
//
// Differences to src/main.cpp, all for the coupled MPMD launch
//   mpirun -np P lmp_hybrid -in deck : -np 1 mpm_solver --coupled
// - MPI_COMM_WORLD is split by colour (coupler::kDemColor; mpm_solver uses kMpmColor) and
//   LAMMPS runs on the LAMMPS-only part, so LAMMPS never sees the MPM ranks. Run alone,
//   the split is a no-op and lmp_hybrid behaves like lmp.
// - the coupler's MPI_Finalize hook is installed, so that the MPM process learns at once
//   when LAMMPS stops on an error (Debian's LAMMPS calls MPI_Finalize + exit(1) there), and
//   the job ends with one MPI_Barrier(MPI_COMM_WORLD) before MPI_Finalize, as LAMMPS's main
//   does with -mpicolor (the end-of-job rule of coupler/protocol.hpp).
// - the integer sizes and the exception setting the fix was compiled with are checked
//   against the library at run time.
#include "abi_check.h"
#include "fix_hybrid_mpm.h"
#include "input.h"
#include "lammps.h"
#include "modify.h"

#include "coupler/protocol.hpp"

#include <mpi.h>

#include <cstdio>
#include <cstdlib>
#include <string>

using namespace LAMMPS_NS;

namespace {

/// Aborts with a clear message if the headers this program was compiled with do not
/// describe the library it runs with.
void check_abi(LAMMPS *lmp)
{
  const std::string bad = hybrid_abi_mismatch(lmp);
  if (!bad.empty()) {
    std::fprintf(stderr,
                 "lmp_hybrid: ERROR: built with LAMMPS headers/defines that do not match the LAMMPS library "
                 "(mismatch:%s); rebuild with tools/setup.sh\n",
                 bad.c_str());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
}

}  // namespace

int main(int argc, char **argv)
{
  MPI_Init(&argc, &argv);

  int me = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &me);
  MPI_Comm lammps_comm = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, coupler::kDemColor, me, &lammps_comm);
  try {
    coupler::install_dem_finalize_hook(lammps_comm);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "lmp_hybrid: ERROR: %s\n", e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  coupler::set_world_barrier_by_hook(true);    // errors: Debian's Error::all -> MPI_Finalize

  try {
    auto *lammps = new LAMMPS(argc, argv, lammps_comm);
    check_abi(lammps);
    (*lammps->modify->fix_map)["hybrid/mpm"] = &FixHybridMPM::creator;
    lammps->input->file();
    delete lammps;
  } catch (fmt::format_error &fe) {
    std::fprintf(stderr, "fmt::format_error: %s\n", fe.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
    std::exit(1);
  }
  // Normal end. If no fix hybrid/mpm ever connected, dem_end_of_job tells the MPM process.
  coupler::set_unconnected_exit_reason(
      "the LAMMPS input ended without a run that uses fix hybrid/mpm - nothing was coupled");
  coupler::dem_end_of_job();    // AbortNote if nothing was coupled, MPI_Barrier(MPI_COMM_WORLD)
  MPI_Comm_free(&lammps_comm);
  MPI_Finalize();
  return 0;
}
