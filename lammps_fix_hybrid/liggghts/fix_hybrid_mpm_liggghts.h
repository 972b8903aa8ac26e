/* -*- c++ -*- ----------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project): the LIGGGHTS
   adapter of the coupling (the host-neutral core is the coupler library;
   the LAMMPS adapter is ../fix_hybrid_mpm*.cpp), split as that one is
   (fix_hybrid_mpm_liggghts_impl.h lists the files). Built into
   liggghts_hybrid; see docs/fix_hybrid_mpm.md, "LIGGGHTS host".
------------------------------------------------------------------------- */

#ifndef LMP_FIX_HYBRID_MPM_LIGGGHTS_H
#define LMP_FIX_HYBRID_MPM_LIGGGHTS_H

#include "fix.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace coupler {
class Link;
class DemSession;
struct StepAck;
struct StepHeader;
struct FixOptions;
struct DemGrains;
struct GrainArrays;
struct GrainRules;
struct EnergyLedger;
class EnergyGuard;
struct CouplingClock;
class DemRunLog;
struct RegionShape;
template <int D> class GrainTransfer;
template <int D> struct PackingTemplate;
template <int D> struct PlannedGrain;
template <int D> struct ZoneAnswer;
template <int D> struct RezonePlan;
template <int D> struct RezoneAtoms;
struct RezoneCounts;
struct RezoneAftermath;
}

namespace LAMMPS_NS {

class FixHybridMPMLiggghts : public Fix {
 public:
  FixHybridMPMLiggghts(class LAMMPS *, int, char **);
  ~FixHybridMPMLiggghts();
  int setmask();
  void init();
  void setup(int);
  void setup_pre_neighbor() { pre_neighbor(); }
  void pre_neighbor();
  void post_integrate();
  void pre_exchange();
  void end_of_step();
  void post_run();
  int modify_param(int, char **);
  double compute_scalar();
  double compute_vector(int);
  double memory_usage();
  void write_restart(FILE *);
  void restart(char *);
  void write_restart_file(char *);

  // per-atom weight, support acceleration and stored stress: they travel with the atoms
  void grow_arrays(int);
  void copy_arrays(int, int, int);
  void set_arrays(int);
  int pack_exchange(int, double *);
  int unpack_exchange(int, double *);
  int pack_restart(int, double *);
  void unpack_restart(int, int);
  int size_restart(int);
  int maxsize_restart();

  /// Creator for Modify's fix map (liggghts_hybrid registers it).
  static Fix *creator(LAMMPS *lmp, int narg, char **arg);

 private:
  std::unique_ptr<coupler::FixOptions> opt;        // the fix line's keywords (coupler/fix_options.hpp)
  std::unique_ptr<coupler::Link> link;             // connection to the MPM process
  std::unique_ptr<coupler::DemSession> session;    // the messages over it
  std::unique_ptr<coupler::StepAck> last_ack;      // of the last exchange or rezone (thermo output)
  std::unique_ptr<coupler::EnergyLedger> ledger;   // the grains' side of the energy ledger
  std::unique_ptr<coupler::DemRunLog> run_log;     // the coupling's wall time, the rezones' summaries
  std::unique_ptr<coupler::GrainTransfer<3>> transfer;
  std::unique_ptr<coupler::PackingTemplate<3>> packing;
  std::vector<signed char> zones;                  // coupler::Zone per grid cell (same on all ranks)
  double *weight;                                  // per-atom share of its material a grain carries
  double **support;                                // per-atom acceleration from the continuum
  double **atom_stress;                            // per-atom stress*volume stored for the next rezone
  std::vector<int> supported;                      // local atoms with a support acceleration
  char *stress_id;                                 // compute stress/atom for the Love-Weber stress
  bigint exchanges, coupled_grains, last_step, vector_step;
  bool converted, rezone_pending, ledger_started;
  bool oracle_pending;    // the zone oracle at the next post_integrate
  std::unique_ptr<coupler::ZoneAnswer<3>> zone_answer;    // its answer where material moves
  bool timestep_checked;          // the DEM time step was checked (and logged) once
  bool restored, state_loaded;    // restarted after the conversion: the MPM process loads its state
  bigint restart_exchanges;       // exchanges read from a restart file
  int new_grain_mask, rezone_source;
  double polydispersity, continuum_start;
  std::unique_ptr<coupler::CouplingClock> clock;    // the coupling's clock (coupler/dem_coupling.hpp)
  double fewest_steps_warned;     // steps per contact at the last warning
  double vector_cache[36];
  std::unique_ptr<coupler::EnergyGuard> guard;    // stops a run whose coupling makes energy
  void ledger_vector(const double grain_totals[7], double *out);    // collective; checks the guard

  void connect();
  void state_request(int kind, const std::string &path);    // save or load the MPM state
  void compute_zones();
  int zone_of(const double *x) const;
  void schedule_rezone(int source);
  void schedule_oracle();
  void store_atom_stress();
  class Compute *stress_compute() const;    // that compute; an error if it was deleted
  std::vector<std::uint64_t> discrete_cells() const;
  std::vector<coupler::RegionShape> discrete_shapes() const;
  std::vector<std::uint64_t> mesh_wall_cells();    // cells the mesh walls pass through now (collective)
  bool mesh_walls_logged = false;
  std::vector<std::string> insertions_warned;    // fix insert/* whose particles this fix does not couple
  void check_insertions();
  void rezone(int source);
  coupler::RezonePlan<3> rezone_plan(int source, double next_time);
  coupler::RezoneAtoms<3> rezone_atoms();
  void check_finite_atoms(const char *before) const;    // an error for a NaN or inf atom
  void report_rezone(int source, const coupler::RezoneCounts &counts, const coupler::StepAck &ack,
                     const coupler::RezoneAftermath &aftermath, const double grains_before[7],
                     const double grains_after[7]);
  bool make_grain(const coupler::PlannedGrain<3> &planned);
  void exchange();
  void log_rezone_summary(bool end_of_run);    // the rezones since the last thermo output, or of the run
  void print_timing_breakdown();              // at the end of a run, before LIGGGHTS's own
  double dem_time(bigint step) const;
  double next_exchange_time(bigint now, bool rezone_next) const;
  coupler::StepHeader step_header(int kind) const;
  coupler::DemGrains grains() const;
  coupler::GrainArrays arrays() const;    // weight, support, atom_stress
  coupler::GrainRules grain_rules() const;
  void grain_totals(double *all) const;
  double grain_energy() const;
  void dem_gravity(double *g) const;
  void check_pair_style() const;
  std::string contact_model() const;    // hooke/stiffness, hooke, hertz or "" (another)
  double material_value(const char *name, bool pair, int type) const;    // fix property/global
  void apply_material();                // keyword material (hooke/stiffness only)
  double dem_steps_per_contact(std::string &why);    // of the stiffest contact (coupler::kBig: not checked)
  void check_dem_timestep(const std::string &when);  // warns when the contacts are poorly resolved
  void say(const std::string &text) const;               // rank 0: screen and log file
  [[noreturn]] void fail(const std::string &why) const;    // error->all with "Fix hybrid/mpm: "
};

}    // namespace LAMMPS_NS

#endif
