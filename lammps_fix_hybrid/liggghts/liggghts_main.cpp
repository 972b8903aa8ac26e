// liggghts_hybrid: LIGGGHTS's main program (as its src/main.cpp) linked with Debian's
// libliggghts, plus the fix style hybrid/mpm registered in the LIGGGHTS instance: the LIGGGHTS
// twin of lmp_hybrid (../main.cpp), with the same rules for the coupled MPMD launch
//   mpirun -np P liggghts_hybrid -in deck : -np 1 mpm_solver --coupled
// - MPI_COMM_WORLD is split by colour (coupler::kDemColor; mpm_solver uses kMpmColor) and
//   LIGGGHTS runs on the DEM-only part. Run alone, the split is a no-op.
// - the coupler's MPI_Finalize hook is installed, so that the MPM process learns at once when
//   LIGGGHTS stops on an error (its Error::all calls MPI_Finalize + exit(1)), and the job ends
//   with one MPI_Barrier(MPI_COMM_WORLD) before MPI_Finalize (coupler/protocol.hpp).
// LIGGGHTS 3.8 keeps its style map Modify::fix_map private and has no plugin loader: the map is
// reached through the one access C++ allows to a private member (liggghts_private.h).
#include "fix_hybrid_mpm_liggghts.h"
#include "liggghts_private.h"
#include "input.h"
#include "lammps.h"
#include "modify.h"

#include "coupler/dem_coupling.hpp"

#include <mpi.h>

#include <map>
#include <string>

using namespace LAMMPS_NS;

namespace LAMMPS_NS::liggghts_private {
struct ModifyFixMap {
  using type = std::map<std::string, Fix *(*)(LAMMPS *, int, char **)> *Modify::*;
  friend type member(ModifyFixMap);
};
template struct Reach<ModifyFixMap, &Modify::fix_map>;
}    // namespace LAMMPS_NS::liggghts_private

int main(int argc, char **argv)
{
  MPI_Comm dem_comm = coupler::start_dem_job(&argc, &argv, "liggghts_hybrid", "LIGGGHTS");

  LAMMPS *liggghts = new LAMMPS(argc, argv, dem_comm);
  (*(liggghts->modify->*member(liggghts_private::ModifyFixMap{})))["hybrid/mpm"] = &FixHybridMPMLiggghts::creator;
  liggghts->input->file();
  delete liggghts;

  // Normal end. If no fix hybrid/mpm ever connected, the MPM process is told.
  coupler::end_dem_job(dem_comm, "the LIGGGHTS input ended without a run that uses fix hybrid/mpm - nothing was coupled");
  return 0;
}
