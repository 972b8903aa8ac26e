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

#include "coupler/dem_coupling.hpp"

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
  MPI_Comm lammps_comm = coupler::start_dem_job(&argc, &argv, "lmp_hybrid", "LAMMPS");

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
  // Normal end. If no fix hybrid/mpm ever connected, the MPM process is told.
  coupler::end_dem_job(lammps_comm,
                       "the LAMMPS input ended without a run that uses fix hybrid/mpm - nothing was coupled");
  return 0;
}
