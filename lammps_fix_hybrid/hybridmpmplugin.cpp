// LAMMPS plugin (PLUGIN package) that adds the fix style hybrid/mpm:
//   plugin load /path/to/hybridmpmplugin.so
// Needs a LAMMPS of the same version as the headers it was built with, with the PLUGIN
// package and started with `-mpicolor 0` in the MPMD launch (tools/hybrid_launch.py --plugin).
#include "lammpsplugin.h"

#include "abi_check.h"
#include "error.h"
#include "fix_hybrid_mpm.h"
#include "lammps.h"
#include "version.h"

#include "coupler/protocol.hpp"

using namespace LAMMPS_NS;

extern "C" void lammpsplugin_init(void *lmp, void *handle, void *regfunc)
{
  auto *lammps = static_cast<LAMMPS *>(lmp);
  const std::string bad = hybrid_abi_mismatch(lmp);
  if (!bad.empty())
    lammps->error->all(FLERR, "hybridmpmplugin.so was built with LAMMPS headers/defines that do not match this "
                              "LAMMPS (mismatch:" + bad + "); rebuild it with tools/setup.sh");

  lammpsplugin_t plugin;
  auto register_plugin = (lammpsplugin_regfunc) regfunc;

  plugin.version = LAMMPS_VERSION;
  plugin.style = "fix";
  plugin.name = "hybrid/mpm";
  plugin.info = "fix hybrid/mpm: coupling to the MPM process mpm_solver (hybrid-granular)";
  plugin.author = "hybrid-granular project";
  plugin.creator.v2 = (lammpsplugin_factory2 *) &FixHybridMPM::creator;
  plugin.handle = handle;
  (*register_plugin)(&plugin, lmp);

  // from now on, an error in the input is passed on to the MPM process at MPI_Finalize
  try {
    coupler::install_dem_finalize_hook(lammps->world, "LAMMPS");
  } catch (const std::exception &e) {
    lammps->error->all(FLERR, std::string("hybridmpmplugin.so: ") + e.what());
  }
}
