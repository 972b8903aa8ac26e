/* -*- c++ -*- ----------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project): what the
   adapter's source files share (fix_hybrid_mpm_liggghts.cpp: lifecycle and
   output; _grains.cpp: the host's grains, contact model and checks;
   _rezone.cpp: zones and rezones; _exchange.cpp: exchanges, the coupling's
   clock, restart, per-atom arrays), as the LAMMPS adapter is split
   (../fix_hybrid_mpm_impl.h). Not part of the fix's interface.
------------------------------------------------------------------------- */

#ifndef LMP_FIX_HYBRID_MPM_LIGGGHTS_IMPL_H
#define LMP_FIX_HYBRID_MPM_LIGGGHTS_IMPL_H

#include "fix_hybrid_mpm_liggghts.h"

#include "domain.h"

#include "coupler/fix_options.hpp"
#include "coupler/grid_geometry.hpp"

#include <string>

namespace LAMMPS_NS {
namespace liggghts_hybrid {

using Vec3 = Eigen::Matrix<double, 3, 1>;

// LIGGGHTS's Error keeps the text it is given and prints it again at the end of the job (its
// SpecialMessages): the text must outlive the call, so the fix's messages are kept for good
const char *kept(const std::string &text);

// the MPM grid over the box (both programs build it from the box, the cell and the touched faces)
inline coupler::GridGeometry<3> box_grid(const Domain *domain, const coupler::FixOptions &options)
{
  return coupler::run_grid<3>(options, domain->boxlo, domain->boxhi);
}

}    // namespace liggghts_hybrid
}    // namespace LAMMPS_NS

#endif
