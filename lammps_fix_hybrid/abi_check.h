/* -*- c++ -*- ----------------------------------------------------------
   Run-time check that fix hybrid/mpm was compiled with the integer sizes
   and exception setting of the LAMMPS library it runs in (lmp_hybrid and
   the plugin both call it when they start).
------------------------------------------------------------------------- */

#ifndef LMP_HYBRID_ABI_CHECK_H
#define LMP_HYBRID_ABI_CHECK_H

#include "info.h"
#include "library.h"
#include "lmptype.h"

#include <string>

namespace LAMMPS_NS {

/// "" if the compile-time settings match the library, else the mismatching names.
inline std::string hybrid_abi_mismatch(void *lmp)
{
  std::string bad;
  if (lammps_extract_setting(lmp, "bigint") != static_cast<int>(sizeof(bigint))) bad += " bigint";
  if (lammps_extract_setting(lmp, "tagint") != static_cast<int>(sizeof(tagint))) bad += " tagint";
  if (lammps_extract_setting(lmp, "imageint") != static_cast<int>(sizeof(imageint))) bad += " imageint";
#ifdef LAMMPS_EXCEPTIONS
  const bool exceptions = true;
#else
  const bool exceptions = false;
#endif
  if (Info::has_exceptions() != exceptions) bad += " LAMMPS_EXCEPTIONS";
  return bad;
}

}    // namespace LAMMPS_NS

#endif
