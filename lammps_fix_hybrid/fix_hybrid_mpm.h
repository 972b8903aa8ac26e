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

#include <array>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace coupler {
class Link;
class DemSession;
struct StepOutcome;
struct GrainRecord;
struct ContinuumSettings;
struct StepAck;
template <int D> struct PlannedGrain;
struct StepHeader;
struct NodeUpdate;
struct GrainView;
struct GrainArrays;
template <int D> struct GridGeometry;
template <int D> struct NodeMomentum;
template <int D> class GrainTransfer;
template <int D> struct PackingTemplate;
template <int D> struct RezoneCell;
template <int D> struct ZoneAnswer;
template <int D> struct RezonePlan;
template <int D> struct RezoneAtoms;
struct RezoneCounts;
struct RezoneAftermath;
template <int D> struct BodySums;
template <int D> struct GrainSums;
struct CellGrains;
struct GrainRules;
struct DemGrains;
struct EnergyLedger;
class EnergyGuard;
struct OracleSettings;
struct FixOptions;
struct RezoneReport;
struct RegionShape;
struct CouplingClock;
class DemRunLog;
}

namespace LAMMPS_NS {
class Compute;
class Region;

class FixHybridMPM : public Fix {
 public:
  FixHybridMPM(class LAMMPS *, int, char **);
  ~FixHybridMPM() override;
  int setmask() override;
  void init() override;
  void setup(int) override;
  void post_integrate() override;
  void pre_exchange() override;
  void setup_post_neighbor() override;
  void post_neighbor() override;
  void end_of_step() override;
  void post_run() override;
  int modify_param(int, char **) override;
  double compute_scalar() override;
  double compute_vector(int) override;
  double memory_usage() override;
  void write_restart(FILE *) override;
  void write_restart_file(const char *) override;
  void restart(char *) override;

  // per-atom hybrid weight: exchanged with the atoms and kept in restart files
  void grow_arrays(int) override;
  void copy_arrays(int, int, int) override;
  void set_arrays(int) override;
  int pack_exchange(int, double *) override;
  int unpack_exchange(int, double *) override;
  int pack_restart(int, double *) override;
  void unpack_restart(int, int) override;
  int size_restart(int) override;
  int maxsize_restart() override;

  /// Creator for the style maps (lmp_hybrid and the plugin register this).
  static Fix *creator(LAMMPS *lmp, int narg, char **arg);

 private:
  std::unique_ptr<coupler::FixOptions> opt;    // the fix line's keywords (coupler/fix_options.hpp)
  void apply_material();
  double container_edge(int axis, int side) const;    // the continuum's container (side 0 lo, 1 hi)

  std::unique_ptr<coupler::Link> link;    // connection to the MPM process (all ranks)
  std::unique_ptr<coupler::DemSession> session;    // the messages over it (coupler/dem_session.hpp)
  bigint exchanges;                       // completed step exchanges (all runs)
  bigint restart_exchanges;               // exchanges read from a restart file
  bigint last_step;                       // last step seen (for the finish message)

  double *weight;                         // per-atom share of its material a grain carries
  // a grain's mass at weight 1 from its radius and the grains' density (rezones give every grain
  // of a moving cell its weight times this)
  double solid_mass(double radius) const;
  coupler::GrainRules grain_rules() const;    // solid density and inertia of the grains
  coupler::GrainArrays arrays() const;        // weight, support, atom_stress (coupler/dem_grains.hpp)
  coupler::DemGrains grains() const;          // this rank's atoms as the coupler sees them (coupler/dem_grains.hpp)
  double **support;                       // per-atom acceleration from the continuum until the next exchange
  std::vector<int> supported;             // local atoms with a support acceleration (valid until reneighboring)
  std::unique_ptr<coupler::GrainTransfer<2>> transfer2;    // grain <-> node transfers (2D runs)
  std::unique_ptr<coupler::GrainTransfer<3>> transfer3;    // (3D runs)
  std::vector<signed char> zones;         // coupler::Zone per grid cell (same on all ranks)
  bool converted;                         // the first rezone happened (points exist)
  bool rezone_pending;                    // a rezone at the next pre_exchange
  int rezone_source;                      // its coupler::ZoneSource
  bool oracle_pending;                    // the zone oracle at the next post_integrate
  // its answer where it moves material, for the rezone at that step's pre_exchange
  std::unique_ptr<coupler::ZoneAnswer<2>> zone_answer2;
  std::unique_ptr<coupler::ZoneAnswer<3>> zone_answer3;
  int new_grain_mask;                     // group bits of grains made from points
  double polydispersity;                  // of the group's diameters, for the packing template
  std::unique_ptr<coupler::PackingTemplate<2>> template2;    // made at the first enrichment
  std::unique_ptr<coupler::PackingTemplate<3>> template3;
  void log_rezone_summary(bool end_of_run);    // the rezones since the last thermo output, or of the run
  bool timestep_checked;                  // the DEM time step was checked (and logged) once
  double fewest_steps_warned;             // steps per contact at the last warning
  bool restored;                          // restarted after the conversion: load the MPM state
  bool state_loaded;                      // the MPM process has loaded it
  std::unique_ptr<coupler::CouplingClock> clock;    // the coupling's clock (coupler/dem_coupling.hpp)
  // per-atom stress*volume (xx yy zz xy xz yz) stored for the next rezone: a per-atom array
  // LAMMPS carries with the atoms (sorting, exchange, other fixes' deletions) like weight
  double **atom_stress = nullptr;
  char *stress_id;                        // compute stress/atom for the Love-Weber stress
  Compute *stress_compute() const;        // that compute; an error if it was deleted
  void dem_gravity(double *g) const;      // the sum of the fix gravity commands' accelerations
  void check_gravity() const;             // an error if it differs from the handshake's
  void check_box() const;                 // an error for a box the grid cannot cover (triclinic)

  // last exchange, for thermo output
  std::unique_ptr<coupler::StepAck> last_ack;
  bigint coupled_grains;
  bigint vector_step;                     // step of the cached thermo vector
  double vector_cache[36];               // f_ID[1..36], docs/fix_hybrid_mpm.md (coupler::ThermoEntry)


  // the grains' side of the energy ledger (coupler/dem_ledger.hpp), this rank's grains
  std::unique_ptr<coupler::EnergyLedger> ledger;
  bool ledger_started;
  double continuum_start;                 // the continuum's energy when the ledger started
  std::unique_ptr<coupler::EnergyGuard> guard;    // stops a run whose coupling makes energy
  double grain_energy() const;            // kinetic (with rotation) + potential, this rank's grains
  void close_dem_bracket();               // LAMMPS's steps since the last bracket

  // where the coupling's wall time goes on this rank (this run's, for the breakdown printed at its
  // end, and all runs', for the thermo vector) and the rezones' summaries (coupler/dem_run_log.hpp)
  std::unique_ptr<coupler::DemRunLog> run_log;
  void print_timing_breakdown();

  void connect();
  template <int D> void rezone(int source);
  template <int D> void ask_oracle();
  template <int D> coupler::RezonePlan<D> rezone_plan(int source);
  template <int D> coupler::RezoneAtoms<D> rezone_atoms();
  template <int D> std::unique_ptr<coupler::ZoneAnswer<D>> &zone_answer();
  void report_rezone(int source, const coupler::RezoneCounts &counts, const coupler::StepAck &ack,
                     const coupler::RezoneAftermath &aftermath, const double grains_before[7],
                     const double grains_after[7]);
  template <int D> bool make_grain(const coupler::PlannedGrain<D> &planned);
  template <int D> const coupler::PackingTemplate<D> &packing_template();
  void schedule_rezone(int source);
  void schedule_oracle();
  double dem_steps_per_contact(std::string &why);
  void check_dem_timestep(const std::string &when);
  void store_atom_stress();
  template <int D> void exchange();
  void check_finite_grains(const std::string &when);
  template <int D> coupler::GrainTransfer<D> &transfer();
  void collect_supported();
  std::vector<coupler::GrainRecord> frame_grains() const;    // this rank's grains for an output frame
  void load_mpm_state();
  void state_request(int kind, const std::string &path);
  void check(const coupler::StepOutcome &mine);    // every rank's outcome; an error if any rank failed
  void compute_zones();
  int zone_of(const double *x) const;
  double dem_time() const;
  coupler::StepHeader step_header(int kind) const;
  double dem_time(bigint step) const;
  double next_exchange_time(bigint now, bool rezone_next) const;
  std::vector<std::uint64_t> discrete_cells();
  std::vector<coupler::RegionShape> discrete_shapes() const;
  std::array<std::pair<const char *, const std::vector<std::string> *>, 2> named_regions() const;
  std::vector<Region *> prematched(const std::vector<std::string> &ids) const;
  static bool in_any(const std::vector<Region *> &regions, double x, double y, double z);
  void grain_defaults();
  void fill_thermo_vector();
  void ledger_vector(const double grain_totals[7], double *out);    // collective; checks the guard
  void grain_totals(double *all) const;
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

E: Fix hybrid/mpm: the time step ... is unstable (checked before the run) ...

Fewer than pi/2 DEM steps per contact of the stiffest pair (the lightest grains, at their
share in hybrid cells): velocity Verlet cannot integrate the contact. Use the timestep the
message names (tc/20).

W: Fix hybrid/mpm: the time step ... resolves the contacts poorly ...

Fewer than 10 (keyword steps_per_contact) DEM steps per contact of the stiffest pair, at
the start of a run or after a rezone made or rescaled grains lighter than any before. See
docs/fix_hybrid_mpm.md, "DEM time step".

W: Fix hybrid/mpm checks the DEM time step for pair styles gran/hooke and gran/hooke/history only ...

Other pair styles: check the step yourself.

E: Fix hybrid/mpm: version mismatch ...

lmp_hybrid (or the plugin) and mpm_solver come from different builds.

*/
