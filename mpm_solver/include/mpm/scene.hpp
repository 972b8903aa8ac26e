#pragma once
// A scene: everything a run needs, in SI units, with defaults for everything
// a config file does not set. Filled by load_scene() (config.hpp) or by code.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "coupler/grid_geometry.hpp"

namespace mpm {

/// Three components; in 2D the third is ignored.
using Vec3 = std::array<double, 3>;

enum class ModelKind { DruckerPrager, MuI };

/// Hyperelastic Drucker-Prager (Klar et al. 2016): Hencky strain, friction-cone
/// return map, no tension. Defaults: medium dense dry sand.
struct DruckerPragerParams {
  double youngs_modulus = 1.0e7;  ///< Pa (continuum, not grain material)
  double poisson_ratio = 0.3;
  double friction_angle_deg = 30.0;
};

/// Hypoelastic mu(I) (Dunatunga & Kamrin 2015). Defaults: glass beads (Jop et al. 2006).
struct MuIParams {
  double youngs_modulus = 1.0e7;  ///< Pa
  double poisson_ratio = 0.3;
  double mu_s = 0.382;
  double mu_2 = 0.644;
  double I0 = 0.279;
  double grain_diameter = 1.0e-3;  ///< m
  double grain_density = 2450.0;   ///< kg/m^3, solid density rho_s
  /// Continuum density (= packing * grain_density) below which the material is
  /// disconnected and carries no stress.
  double critical_density = 0.6 * 2450.0;
};

struct Material {
  std::string name;
  ModelKind model = ModelKind::DruckerPrager;
  double density = 1600.0;  ///< kg/m^3, bulk density of the continuum
  DruckerPragerParams drucker_prager;
  MuIParams mu_i;
};

enum class Shape { Box, Cylinder };

/// A region filled with material points on a regular lattice.
struct Block {
  std::string material;  ///< name of a Material
  Shape shape = Shape::Box;
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};  ///< Box
  Vec3 center{0, 0, 0};                 ///< Cylinder (a disk in 2D)
  double radius = 0;                    ///< Cylinder
  int axis = 2;                         ///< Cylinder axis in 3D (0, 1, 2)
  double height = 0;                    ///< Cylinder length along axis in 3D, centred on center
  int points_per_cell = 0;              ///< 0: default (2 per axis, i.e. 4 in 2D, 8 in 3D)
  Vec3 velocity{0, 0, 0};               ///< initial velocity
  /// Initialise the stress to the lithostatic (geostatic) state under gravity,
  /// with lateral stress ratio k0, measured from the block's top.
  bool geostatic = false;
  double k0 = 0.5;
};

/// How a boundary acts on grid velocities moving into it.
enum class Contact { Sticky, Slip, Friction };

enum class BoundaryKind { Plane, Box };

struct Boundary {
  BoundaryKind kind = BoundaryKind::Plane;
  Contact contact = Contact::Slip;
  double friction = 0.0;     ///< Coulomb coefficient, Contact::Friction only
  bool separating = true;    ///< false: also holds material that moves away (no lift-off)
  Vec3 point{0, 0, 0};       ///< Plane: a point on it (at time 0)
  Vec3 normal{0, 1, 0};      ///< Plane: unit normal pointing into the material side
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};  ///< Box at time 0
  bool inside = false;       ///< Box: true = material kept inside (container), false = obstacle
  Vec3 velocity{0, 0, 0};    ///< prescribed rigid velocity (moving plate or intruder)
};

/// A sink: material points that enter the box leave the run, their mass counted as outflow
/// (a silo's orifice, the end of a chute).
struct Outlet {
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};
};

struct GridSpec {
  double cell_size = 0;  ///< dx, m (required)
  Vec3 lower{0, 0, 0}, upper{0, 0, 0};  ///< domain; material outside it is an error
  /// Per axis, a plane the nodes are laid on (a coupled run's touched container face,
  /// coupler::touched_walls); NaN: the nodes start at `lower`.
  Vec3 node_plane = coupler::kNoWalls;
  /// Condition the domain faces impose, like a box container around the scene.
  Contact walls = Contact::Slip;
  double wall_friction = 0.0;
};

struct TimeSpec {
  double end_time = 1.0;  ///< s
  double cfl = 0.5;       ///< dt = cfl * dx / (c + |v|max)
  /// >0: a fixed step the user chose; refused if above the stable step.
  double fixed_dt = 0.0;
  /// Viscous damping rate of grid velocities, 1/s (v *= 1 - damping*dt).
  /// For settling quasi-static states only; 0 for dynamics.
  double damping = 0.0;
};

struct OutputSpec {
  std::string directory = "mpm_output";
  double interval = 0.0;      ///< simulated seconds between snapshots; 0 = first and last only
  bool grid_fields = false;   ///< also write grid mass and velocity
  double progress_interval = 5.0;  ///< wall seconds between progress lines; 0 = none
  double outflow_interval = 0.005; ///< simulated seconds between lines of outflow.dat (scenes with outlets)
};

struct Scene {
  int dimension = 2;
  /// Coupled run: the points come from the DEM side (Solver::add_point), not from blocks.
  bool coupled = false;
  Vec3 gravity{0, -9.81, 0};  ///< default: -9.81 m/s^2 along the last axis
  GridSpec grid;
  TimeSpec time;
  OutputSpec output;
  std::vector<Material> materials;
  std::vector<Block> blocks;
  std::vector<Boundary> boundaries;
  std::vector<Outlet> outlets;
};

}  // namespace mpm
