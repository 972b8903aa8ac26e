/* -*- c++ -*- ----------------------------------------------------------
   fix hybrid/mpm: couples LAMMPS grains to the MPM process mpm_solver
   (hybrid-granular project). Built into lmp_hybrid and into the plugin
   hybridmpmplugin.so; see docs/fix_hybrid_mpm.md.
------------------------------------------------------------------------- */

#ifdef FIX_CLASS
// clang-format off
FixStyle(hybrid/mpm,FixHybridMPM);
// clang-format on
#else

#ifndef LMP_FIX_HYBRID_MPM_H
#define LMP_FIX_HYBRID_MPM_H

#include "fix.h"

#include <memory>

namespace coupler {
class Link;
}

namespace LAMMPS_NS {

class FixHybridMPM : public Fix {
 public:
  FixHybridMPM(class LAMMPS *, int, char **);
  ~FixHybridMPM() override;
  int setmask() override;
  void init() override;
  void setup(int) override;
  void end_of_step() override;
  void post_run() override;
  double compute_scalar() override;
  double memory_usage() override;
  void write_restart(FILE *) override;
  void restart(char *) override;

  /// Creator for the style maps (lmp_hybrid and the plugin register this).
  static Fix *creator(LAMMPS *lmp, int narg, char **arg);

 private:
  double cell;            // MPM grid cell size (distance units, m)
  double reply_timeout;   // s LAMMPS waits for each reply of the MPM process
  double idle_timeout;    // s the MPM process waits for the next message from LAMMPS
  int model;              // coupler::ModelId
  int every;              // exchange every this many steps

  std::unique_ptr<coupler::Link> link;    // connection to the MPM process (all ranks)
  bigint exchanges;                       // completed step exchanges (all runs)
  bigint restart_exchanges;               // exchanges read from a restart file
  bigint last_step;                       // last step seen (for the finish message)

  void connect();
  void fail(const char *file, int line, int status, const char *what);
  [[noreturn]] void illegal(const std::string &why);
};

}    // namespace LAMMPS_NS

#endif
#endif

/* ERROR/WARNING messages:

E: Illegal fix hybrid/mpm command: ...

The fix line has an unknown keyword, a keyword without its value, or a value
out of range; the message names the keyword. See docs/fix_hybrid_mpm.md.

E: Fix hybrid/mpm requires keyword cell

The MPM grid cell size has no default.

E: Fix hybrid/mpm requires atom style sphere

Grains need per-atom radius and mass.

E: Fix hybrid/mpm requires units si

The MPM process works in SI units.

E: Fix hybrid/mpm: no MPM process in this MPI job ...

LAMMPS was started without mpm_solver in the same mpirun command (or a stock
LAMMPS without -mpicolor 0). Use tools/hybrid_launch.py.

E: Fix hybrid/mpm: no reply from the MPM process within N s ...

The MPM process hung or crashed. The job is aborted, because MPI_Finalize
would wait for it forever.

E: Fix hybrid/mpm: version mismatch ...

lmp_hybrid (or the plugin) and mpm_solver come from different builds.

*/
