/* -*- c++ -*- ----------------------------------------------------------
   hybrid-granular: reaching a private member of LIGGGHTS 3.8, which has
   no accessor for what the fix needs (Modify's style map, Output's restart
   schedule, Thermo's count of atoms at its last output)
------------------------------------------------------------------------- */

#ifndef LMP_LIGGGHTS_PRIVATE_H
#define LMP_LIGGGHTS_PRIVATE_H

namespace LAMMPS_NS {
namespace liggghts_private {

// An explicit template instantiation may name a private member; the friend function it
// defines hands the member's pointer out. One member, one tag in this namespace:
//   struct ThermoLastNatoms { using type = bigint Thermo::*; friend type member(ThermoLastNatoms); };
//   template struct Reach<ThermoLastNatoms, &Thermo::last_natoms>;    // in one source file
//   thermo->*member(ThermoLastNatoms{})
template <class Tag, typename Tag::type Member>
struct Reach {
  friend typename Tag::type member(Tag) { return Member; }
};

}    // namespace liggghts_private
}    // namespace LAMMPS_NS

#endif
