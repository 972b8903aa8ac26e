/* -*- c++ -*- ----------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project): what its source files share
   (fix_hybrid_mpm.cpp: lifecycle and output; _grains.cpp: the host's
   grains, settings and checks; _rezone.cpp: zones and rezones;
   _exchange.cpp: exchanges, restart, per-atom arrays). Not part of the
   fix's interface.
------------------------------------------------------------------------- */

#ifndef LMP_FIX_HYBRID_MPM_IMPL_H
#define LMP_FIX_HYBRID_MPM_IMPL_H

#include "fix_hybrid_mpm.h"

#include "domain.h"

#include "coupler/conversion.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/grid_geometry.hpp"
#include "coupler/transfer.hpp"

namespace LAMMPS_NS {
namespace hybrid_mpm {

// per-atom values that travel with a grain (pack_exchange): weight, support (3), stored stress (6)
inline constexpr int kPerAtomValues = coupler::GrainArrays::kValues;

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

// the MPM grid over the box (both programs build it from the box, the cell and the touched faces)
template <int D>
coupler::GridGeometry<D> box_grid(const Domain *domain, const coupler::FixOptions &options)
{
  return coupler::run_grid<D>(options, domain->boxlo, domain->boxhi);
}

}    // namespace hybrid_mpm

// the grain <-> node transfers of a 2D or 3D run (fix_hybrid_mpm_rezone.cpp)
template <> coupler::GrainTransfer<2> &FixHybridMPM::transfer<2>();
template <> coupler::GrainTransfer<3> &FixHybridMPM::transfer<3>();

}    // namespace LAMMPS_NS

#endif
