#pragma once
// The continuum of a coupled run: an MPM solver whose grid covers the DEM box, whose points
// are made from grains, and which agrees with the grains on the node velocities of the
// hybrid zone (docs/design.md section 5). No MPI here: coupled.cpp moves the messages.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/protocol.hpp"
#include "coupler/support_force.hpp"
#include "coupler/zones.hpp"
#include "mpm/output.hpp"
#include "mpm/solver.hpp"

namespace mpm {

/// The scene of a coupled run, from the fix's Hello.
Scene coupled_scene(const coupler::Hello& hello);

template <int D>
class CoupledContinuum {
 public:
  /// Throws UserError if the settings do not make a valid continuum.
  explicit CoupledContinuum(const coupler::Hello& hello);

  /// First half of a rezone (coupler/protocol.hpp): the new zones - `given` (zone_source
  /// kZonesGiven) or the oracle's, from the grains' sums per cell of every DEM rank and the
  /// points - and the cells whose material moves, with what new grains there must carry.
  /// `oracle`: its settings and `discrete_cells` the cells it takes as boundaries (the fix's
  /// discrete regions), both not used with given zones. `time`: the DEM time (the start of the continuum's clock at the first rezone).
  std::vector<coupler::RezoneCell<D>> plan_rezone(double time, int zone_source, const std::vector<std::int8_t>& given,
                                                  const coupler::OracleSettings& oracle,
                                                  const std::vector<std::uint64_t>& discrete_cells,
                                                  const std::vector<std::vector<coupler::CellGrains>>& grains);
  /// Second half: with every DEM rank's grain sums in those cells (old grains, and the new
  /// ones the DEM side made where the plan asked), moves the points' part (correct, remove or
  /// make points) and returns what the grains of each cell become. Exact: every grain ends at
  /// its zone's weight times its solid mass, the cell's points take the rest of its material,
  /// and what they cannot (a discrete cell) goes to the points of the nearest cells that stay
  /// continuum or hybrid.
  std::vector<coupler::GrainCorrection<D>> complete_rezone(
      const std::vector<std::vector<coupler::GrainSums<D>>>& grains);
  const std::vector<std::int8_t>& zones() const { return zones_; }
  /// After a rezone: balances the points' reaction to the support force against the grains'
  /// total support force (sum m a), which the rezone changed.
  void balance_support(const Vec<D>& grain_force);

  /// Advances the continuum to `time` in stable substeps and stops inside the last one,
  /// after its grid update: the grid then holds the node velocities at `time`. Does nothing
  /// if it already stands there (advanced ahead while the DEM host computed its steps).
  void advance_to(double time);
  /// The velocity agreement on the nodes the DEM ranks sent (NodeRecord lists, one per
  /// rank); returns the answers in the same order. Call between advance_to and complete_step.
  /// With field_shares, each answer also carries the node's share of the field rule: the
  /// continuum's flow regime there (coupler/flow_regime.hpp) times the agreement's closing.
  std::vector<std::vector<coupler::NodeUpdate>> agree(const std::vector<std::vector<coupler::NodeRecord>>& per_rank,
                                                      bool field_shares = false);
  /// The continuum's totals from the agreed grid: what the points hold after complete_step
  /// (APIC's G2P keeps mass, momentum and angular momentum), known before it runs.
  coupler::StepAck grid_totals(std::int64_t step) const;
  /// Completes the open substep (G2P with the agreed grid velocities).
  void complete_step();
  /// The continuum's totals from its points (no substep may be open).
  coupler::StepAck totals(std::int64_t step) const;
  bool step_open() const { return pending_dt_ >= 0; }

  /// Saves the exact state to `path` (HDF5, mpm/state_file.hpp); throws UserError.
  void save(const std::string& path, std::int64_t dem_step, std::int64_t exchanges) const;
  /// Continues from a saved state; throws UserError if it does not fit this run's grid.
  void load(const std::string& path);

  /// Writes one frame (points, grid and the grains the DEM ranks sent).
  void write_frame(const std::vector<std::vector<coupler::GrainRecord>>& grains, std::int64_t step);

  const Solver<D>& solver() const { return solver_; }
  double time() const { return time_; }

  /// What the rezones did to the points' energy so far (J; J/m in 2D), by what they did to them:
  /// points made (homogenisation), removed (for grains, or renewed), corrected onto their cell's
  /// part, and the rests handed to points nearby, each as kinetic (with APIC's affine part),
  /// potential and elastic energy. The four sum to the ledger's rezone term (rezone_ledger).
  struct RezoneEnergy {
    struct Parts {
      double kinetic = 0, potential = 0, elastic = 0;
      double total() const { return kinetic + potential + elastic; }
      Parts& operator+=(const Parts& o) {
        kinetic += o.kinetic, potential += o.potential, elastic += o.elastic;
        return *this;
      }
      Parts& operator-=(const Parts& o) {
        kinetic -= o.kinetic, potential -= o.potential, elastic -= o.elastic;
        return *this;
      }
      Parts operator-(const Parts& o) const { return Parts(*this) -= o; }
    };
    Parts made, removed, corrected, rests;
    /// the same changes by the cells' zone change (a rest by its giving cell's)
    Parts by_mechanism[coupler::kMechanisms];
    double total() const { return made.total() + removed.total() + corrected.total() + rests.total(); }
  };
  const RezoneEnergy& rezone_energy() const { return rezone_energy_; }

  /// pic regime's shares over the run's exchanges, weighted by the grains' mass at the nodes
  /// (each exchange's m_dem): how much of the coupled grains' mass took the field rule whole
  /// (share 1, quasi-static), none of it (0, flowing) or in part, and the mean share before and
  /// after the agreement's closing. Tells where a run's grains are held to the continuum's field.
  struct FieldRuleTally {
    double mass = 0, quasi_static = 0, flowing = 0, share = 0, applied = 0;
  };
  const FieldRuleTally& field_rule_tally() const { return field_rule_; }
  /// The continuum's rezone term of the energy ledger: the points' energy the rezones changed.
  double rezone_ledger() const { return ledger_.rezone; }

 private:
  /// Sets the points' loads until the next exchange from the last agreement's nodes: the
  /// reaction to the support force (body_accel) and the fill pressure (fill_pressure).
  void apply_exchange_loads();
  /// Share of a cell's material its grains carry in a zone (1 discrete, the weight hybrid).
  double grain_share(int zone) const;
  /// A planned cell of a rezone: its plan, its points (indices) and their sums.
  struct MovingCell {
    coupler::RezoneCell<D> plan;
    coupler::RezoneMechanism mechanism = coupler::kRepair;    ///< by its zone change
    coupler::BodySums<D> points;
    std::vector<std::size_t> members;
  };
  std::vector<MovingCell> moving_;
  /// A cell rezoned only to repair its grains (starved in a hybrid zone: no room to make grains;
  /// light in a discrete one: no points near that can give their missing mass) may be left as it
  /// was, and would be planned again at every oracle step (a 100 d collapse near rest: the same 2
  /// cells at every one, each a rezone, its neighbour lists rebuilt, and the deposit came to rest
  /// a tenth later). Where its material is at rest (coupler::material_at_rest) it is repaired
  /// again once its grains' volume or carried mass or its number of points changed (a grain or a
  /// point came or left), beyond round-off; moving material is repaired at every oracle step (the
  /// repair also gives grains and points the cell's motion: skipping it in a flow changed a 100 d
  /// collapse's runout from +1.7 % to -6 %).
  struct Repair {
    double grain_volume = -1;    ///< at its last repair (-1: none since its last other rezone)
    double grain_mass = 0;
    std::uint32_t points = 0;
    bool same(double volume, double mass, std::uint32_t count) const {
      auto near = [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b)); };
      return grain_volume >= 0 && count == points && near(volume, grain_volume) && near(mass, grain_mass);
    }
  };
  std::vector<Repair> repairs_;
  /// The grains' carried mass per cell (plan_rezone's sums; complete_rezone sets the moving cells').
  std::vector<double> cell_grain_mass_;
  std::int64_t zone_cells_[3] = {0, 0, 0};
  std::vector<std::uint8_t> cell_in_box_;  ///< cells whose centre lies in the DEM box (zone_cells_ counts them)
  std::int64_t moved_cells_ = 0, points_made_ = 0, points_removed_ = 0;
  std::int64_t rest_moved_ = 0;  ///< last rezone: cells whose rest of material went to nearby points
  std::int64_t rest_kept_ = 0;   ///< and cells that kept it (no points near enough to take it)
  /// Adds point p to sums (APIC spin and inertia), about `reference`.
  void add_point_body(coupler::BodySums<D>& sums, std::size_t p, const Vec<D>& reference) const;
  /// Applies a rigid correction to points (mass and volume scaled, velocity and C incremented).
  void correct_points(const std::vector<std::size_t>& members, const coupler::RigidCorrection<D>& fix);
  /// The kinetic energy such a correction would add to the points.
  double energy_created(const std::vector<std::size_t>& members, const coupler::RigidCorrection<D>& fix) const;
  coupler::StepAck before_;           ///< the continuum's totals before the last rezone

  /// The continuum's side of the energy ledger (docs/fix_hybrid_mpm.md, "Energy ledger").
  /// Brackets that follow each other without a gap: the agreed grid of one exchange, the
  /// continuum's own steps (with any rezone measured apart), the grid before the next
  /// agreement, the agreement. So energy = energy at the start + physics + agreement + rezone.
  struct EnergyLedger {
    double energy = 0;      ///< kinetic + potential at the end of the last bracket
    double physics = 0, agreement = 0, rezone = 0;
    double fill_start = 0;  ///< Solver::fill_work when the ledger started
  };
  EnergyLedger ledger_;
  double rezone_start_energy_ = 0;    ///< the points' energy when the rezone began
  RezoneEnergy rezone_energy_;
  /// The energy of the points `members`, in RezoneEnergy's parts (point_energy's terms).
  typename RezoneEnergy::Parts energy_parts(const std::vector<std::size_t>& members) const;
  /// Kinetic plus potential energy of the grid (velocities after the grid update) and of the
  /// points. Quadratic B-splines reproduce positions, so both give the same potential energy.
  /// Both add the elastic energy the points' stress stores.
  double grid_energy() const;
  double point_energy() const;
  double elastic_energy() const;
  double elastic_energy(std::size_t p) const;  ///< point p's
  double potential(double mass, const Vec<D>& x) const;
  coupler::StepAck ack(std::int64_t step, double mass, const Vec<D>& momentum, const coupler::Spin<D>& angular,
                       double kinetic_energy) const;

  coupler::Hello hello_;
  Solver<D> solver_;
  std::vector<std::int8_t> zones_;
  double time_ = 0;                   ///< DEM time of the continuum's state
  double pending_dt_ = -1;            ///< substep left open by advance_to (< 0: none)
  double open_time_ = 0;              ///< the time advance_to stopped at
  int substeps_ = 0;
  double mismatch_ = 0;
  double overlap_ = 0;               ///< StepAck::overlap of the last exchange
  std::int64_t shared_nodes_ = 0;
  std::vector<double> dem_mass_;      ///< scratch: DEM node mass, touched nodes only
  std::vector<Vec<D>> dem_momentum_;
  std::vector<std::size_t> touched_;
  /// The speed below which material is still: kRestSpeed sqrt(g d) (0 without gravity).
  double rest_speed() const;
  /// The field shares of the touched nodes (touched_ order), from the points' inertial numbers
  /// and speeds.
  std::vector<double> touched_field_shares();
  std::vector<std::uint8_t> reaching_base_;  ///< scratch of touched_field_shares, all 0 between calls
  FieldRuleTally field_rule_;
  std::vector<std::int64_t> touched_slot_;  ///< node -> index in touched_, -1 if untouched
  double interval_ = 0;               ///< time since the previous exchange, s
  std::vector<coupler::SupportNode<D>> support_;  ///< each node's support force until the next exchange
  std::vector<std::size_t> support_nodes_;  ///< nodes where a support force is set
  /// The fill pressure (docs/design.md section 5.4): its modulus (Pa, 0 = none), the mass of a node
  /// at the packing, and the last agreement's pressure per node.
  double fill_modulus_ = 0, full_node_mass_ = 0;
  std::vector<double> fill_pressure_;
  std::vector<std::size_t> fill_nodes_;     ///< nodes where fill_pressure_ is set
  std::unique_ptr<SnapshotWriter<D>> writer_;
};

}  // namespace mpm
