#pragma once
// Layout pins of the wire structs (coupler/protocol.hpp). The structs travel as raw bytes
// between two programs built separately (LAMMPS's fix with LAMMPS's flags, mpm_solver with its
// own), so the offset and size of every field and the size of every struct are part of protocol
// version kProtocolVersion. A compiler, flag or edit that moves any of them fails here rather
// than corrupting messages. There is no implicit padding: the `pad` fields spell it out, so
// every byte sent is defined. Changing a layout: bump kProtocolVersion (coupler/version.hpp)
// and update these lines together.
#include <cstddef>
#include <type_traits>

#include "coupler/protocol.hpp"

namespace coupler::wire_layout {

static_assert(kProtocolVersion == 15, "the layouts below are those of protocol 15: update them with the version");

#define COUPLER_WIRE_SIZE(T, size)                                                                     \
  static_assert(std::is_standard_layout_v<T> && std::is_trivially_copyable_v<T>,                      \
                #T " is sent as bytes: it must be standard-layout and trivially copyable");          \
  static_assert(sizeof(T) == (size), "sizeof(" #T ") changed: the wire layout changed")
#define COUPLER_WIRE_FIELD(T, f, offset, size) \
  static_assert(offsetof(T, f) == (offset) && sizeof(T::f) == (size), #T "::" #f " moved: the wire layout changed")

COUPLER_WIRE_SIZE(ContinuumSettings, 496);
COUPLER_WIRE_FIELD(ContinuumSettings, youngs_modulus, 0, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, poisson_ratio, 8, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, friction_angle_deg, 16, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, mu_s, 24, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, mu_2, 32, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, I0, 40, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, grain_diameter, 48, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, grain_density, 56, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, critical_packing, 64, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, gravity, 72, 24);
COUPLER_WIRE_FIELD(ContinuumSettings, wall_contact, 96, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, pad0, 100, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, wall_friction, 104, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, container_lo, 112, 24);
COUPLER_WIRE_FIELD(ContinuumSettings, container_hi, 136, 24);
COUPLER_WIRE_FIELD(ContinuumSettings, touched_faces, 160, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, pad1, 164, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, cfl, 168, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, grain_weight, 176, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, pic, 184, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, agreement_time, 192, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, support_gain, 200, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, fill_share, 208, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, fill_modulus, 216, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, packing_fraction, 224, 8);
COUPLER_WIRE_FIELD(ContinuumSettings, points_per_axis, 232, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, output_every, 236, 4);
COUPLER_WIRE_FIELD(ContinuumSettings, output_path, 240, 256);

COUPLER_WIRE_SIZE(Hello, 688);
COUPLER_WIRE_FIELD(Hello, protocol, 0, 4);
COUPLER_WIRE_FIELD(Hello, release, 4, 32);
COUPLER_WIRE_FIELD(Hello, host, 36, 32);
COUPLER_WIRE_FIELD(Hello, units, 68, 8);
COUPLER_WIRE_FIELD(Hello, dimension, 76, 4);
COUPLER_WIRE_FIELD(Hello, dem_ranks, 80, 4);
COUPLER_WIRE_FIELD(Hello, model, 84, 4);
COUPLER_WIRE_FIELD(Hello, mpm_every, 88, 4);
COUPLER_WIRE_FIELD(Hello, pad, 92, 4);
COUPLER_WIRE_FIELD(Hello, cell, 96, 8);
COUPLER_WIRE_FIELD(Hello, dt, 104, 8);
COUPLER_WIRE_FIELD(Hello, reply_timeout, 112, 8);
COUPLER_WIRE_FIELD(Hello, idle_timeout, 120, 8);
COUPLER_WIRE_FIELD(Hello, box_lo, 128, 24);
COUPLER_WIRE_FIELD(Hello, box_hi, 152, 24);
COUPLER_WIRE_FIELD(Hello, step, 176, 8);
COUPLER_WIRE_FIELD(Hello, time, 184, 8);
COUPLER_WIRE_FIELD(Hello, continuum, 192, 496);

COUPLER_WIRE_SIZE(HelloReply, 300);
COUPLER_WIRE_FIELD(HelloReply, protocol, 0, 4);
COUPLER_WIRE_FIELD(HelloReply, release, 4, 32);
COUPLER_WIRE_FIELD(HelloReply, ok, 36, 4);
COUPLER_WIRE_FIELD(HelloReply, mpm_ranks, 40, 4);
COUPLER_WIRE_FIELD(HelloReply, message, 44, 256);

COUPLER_WIRE_SIZE(CellGrains, 32);
COUPLER_WIRE_FIELD(CellGrains, cell, 0, 8);
COUPLER_WIRE_FIELD(CellGrains, volume, 8, 8);
COUPLER_WIRE_FIELD(CellGrains, mass, 16, 8);
COUPLER_WIRE_FIELD(CellGrains, kinetic, 24, 8);

COUPLER_WIRE_SIZE(StateRequest, 4104);
COUPLER_WIRE_FIELD(StateRequest, path, 0, 4096);
COUPLER_WIRE_FIELD(StateRequest, exchanges, 4096, 8);

COUPLER_WIRE_SIZE(StepHeader, 56);
COUPLER_WIRE_FIELD(StepHeader, step, 0, 8);
COUPLER_WIRE_FIELD(StepHeader, time, 8, 8);
COUPLER_WIRE_FIELD(StepHeader, dt, 16, 8);
COUPLER_WIRE_FIELD(StepHeader, kind, 24, 4);
COUPLER_WIRE_FIELD(StepHeader, output, 28, 4);
COUPLER_WIRE_FIELD(StepHeader, n_grains, 32, 8);
COUPLER_WIRE_FIELD(StepHeader, next_time, 40, 8);
COUPLER_WIRE_FIELD(StepHeader, zone_source, 48, 4);
COUPLER_WIRE_FIELD(StepHeader, field_shares, 52, 4);

COUPLER_WIRE_SIZE(StepAck, 536);
COUPLER_WIRE_FIELD(StepAck, step, 0, 8);
COUPLER_WIRE_FIELD(StepAck, status, 8, 4);
COUPLER_WIRE_FIELD(StepAck, substeps, 12, 4);
COUPLER_WIRE_FIELD(StepAck, message, 16, 256);
COUPLER_WIRE_FIELD(StepAck, points, 272, 8);
COUPLER_WIRE_FIELD(StepAck, shared_nodes, 280, 8);
COUPLER_WIRE_FIELD(StepAck, mass, 288, 8);
COUPLER_WIRE_FIELD(StepAck, momentum, 296, 24);
COUPLER_WIRE_FIELD(StepAck, angular, 320, 24);
COUPLER_WIRE_FIELD(StepAck, kinetic_energy, 344, 8);
COUPLER_WIRE_FIELD(StepAck, mismatch, 352, 8);
COUPLER_WIRE_FIELD(StepAck, mpm_dt, 360, 8);
COUPLER_WIRE_FIELD(StepAck, zone_cells, 368, 24);
COUPLER_WIRE_FIELD(StepAck, moved_cells, 392, 8);
COUPLER_WIRE_FIELD(StepAck, points_made, 400, 8);
COUPLER_WIRE_FIELD(StepAck, points_removed, 408, 8);
COUPLER_WIRE_FIELD(StepAck, rests_moved, 416, 8);
COUPLER_WIRE_FIELD(StepAck, rests_kept, 424, 8);
COUPLER_WIRE_FIELD(StepAck, before, 432, 56);
COUPLER_WIRE_FIELD(StepAck, energy, 488, 8);
COUPLER_WIRE_FIELD(StepAck, energy_physics, 496, 8);
COUPLER_WIRE_FIELD(StepAck, energy_agreement, 504, 8);
COUPLER_WIRE_FIELD(StepAck, energy_rezone, 512, 8);
COUPLER_WIRE_FIELD(StepAck, overlap, 520, 8);
COUPLER_WIRE_FIELD(StepAck, energy_fill, 528, 8);

COUPLER_WIRE_SIZE(NodeRecord, 40);
COUPLER_WIRE_FIELD(NodeRecord, node, 0, 8);
COUPLER_WIRE_FIELD(NodeRecord, mass, 8, 8);
COUPLER_WIRE_FIELD(NodeRecord, momentum, 16, 24);

COUPLER_WIRE_SIZE(NodeUpdate, 80);
COUPLER_WIRE_FIELD(NodeUpdate, velocity, 0, 24);
COUPLER_WIRE_FIELD(NodeUpdate, impulse_per_mass, 24, 24);
COUPLER_WIRE_FIELD(NodeUpdate, support, 48, 24);
COUPLER_WIRE_FIELD(NodeUpdate, field_share, 72, 8);

COUPLER_WIRE_SIZE(GrainRecord, 88);
COUPLER_WIRE_FIELD(GrainRecord, id, 0, 8);
COUPLER_WIRE_FIELD(GrainRecord, x, 8, 24);
COUPLER_WIRE_FIELD(GrainRecord, v, 32, 24);
COUPLER_WIRE_FIELD(GrainRecord, radius, 56, 8);
COUPLER_WIRE_FIELD(GrainRecord, mass, 64, 8);
COUPLER_WIRE_FIELD(GrainRecord, weight, 72, 8);
COUPLER_WIRE_FIELD(GrainRecord, zone, 80, 4);
COUPLER_WIRE_FIELD(GrainRecord, pad, 84, 4);

COUPLER_WIRE_SIZE(Finish, 16);
COUPLER_WIRE_FIELD(Finish, step, 0, 8);
COUPLER_WIRE_FIELD(Finish, exchanges, 8, 8);

COUPLER_WIRE_SIZE(AbortNote, 256);
COUPLER_WIRE_FIELD(AbortNote, reason, 0, 256);

COUPLER_WIRE_SIZE(OracleSettings, 56);
COUPLER_WIRE_FIELD(OracleSettings, surface_packing, 0, 8);
COUPLER_WIRE_FIELD(OracleSettings, continuum_depth, 8, 8);
COUPLER_WIRE_FIELD(OracleSettings, band, 16, 8);
COUPLER_WIRE_FIELD(OracleSettings, dilute_packing, 24, 8);
COUPLER_WIRE_FIELD(OracleSettings, max_shear_rate, 32, 8);
COUPLER_WIRE_FIELD(OracleSettings, surface_depth, 40, 8);
COUPLER_WIRE_FIELD(OracleSettings, rest_hold, 48, 8);

COUPLER_WIRE_SIZE(CellMoments<2>, 96);
COUPLER_WIRE_FIELD(CellMoments<2>, cell, 0, 8);
COUPLER_WIRE_FIELD(CellMoments<2>, count, 8, 8);
COUPLER_WIRE_FIELD(CellMoments<2>, mass, 16, 8);
COUPLER_WIRE_FIELD(CellMoments<2>, first_moment_, 24, 16);
COUPLER_WIRE_FIELD(CellMoments<2>, momentum_, 40, 16);
COUPLER_WIRE_FIELD(CellMoments<2>, angular_, 56, 8);
COUPLER_WIRE_FIELD(CellMoments<2>, stress_volume_, 64, 32);

COUPLER_WIRE_SIZE(BodySums<2>, 192);
COUPLER_WIRE_FIELD(BodySums<2>, moments, 0, 96);
COUPLER_WIRE_FIELD(BodySums<2>, inertia_, 96, 32);
COUPLER_WIRE_FIELD(BodySums<2>, velocity_moment_, 128, 32);
COUPLER_WIRE_FIELD(BodySums<2>, position_moment_, 160, 32);

COUPLER_WIRE_SIZE(RezoneCell<2>, 160);
COUPLER_WIRE_FIELD(RezoneCell<2>, cell, 0, 8);
COUPLER_WIRE_FIELD(RezoneCell<2>, zone, 8, 4);
COUPLER_WIRE_FIELD(RezoneCell<2>, make_grains, 12, 4);
COUPLER_WIRE_FIELD(RezoneCell<2>, points, 16, 96);
COUPLER_WIRE_FIELD(RezoneCell<2>, gradient, 112, 32);
COUPLER_WIRE_FIELD(RezoneCell<2>, occupancy, 144, 8);
COUPLER_WIRE_FIELD(RezoneCell<2>, grain_weight, 152, 8);

COUPLER_WIRE_SIZE(GrainSums<2>, 384);
COUPLER_WIRE_FIELD(GrainSums<2>, carried, 0, 192);
COUPLER_WIRE_FIELD(GrainSums<2>, solid, 192, 192);

COUPLER_WIRE_SIZE(GrainCorrection<2>, 72);
COUPLER_WIRE_FIELD(GrainCorrection<2>, cell, 0, 8);
COUPLER_WIRE_FIELD(GrainCorrection<2>, remove, 8, 4);
COUPLER_WIRE_FIELD(GrainCorrection<2>, mechanism, 12, 4);
COUPLER_WIRE_FIELD(GrainCorrection<2>, weight, 16, 8);
COUPLER_WIRE_FIELD(GrainCorrection<2>, mass_factor, 24, 8);
COUPLER_WIRE_FIELD(GrainCorrection<2>, velocity, 32, 16);
COUPLER_WIRE_FIELD(GrainCorrection<2>, omega, 48, 8);
COUPLER_WIRE_FIELD(GrainCorrection<2>, centre, 56, 16);

COUPLER_WIRE_SIZE(CellMoments<3>, 168);
COUPLER_WIRE_FIELD(CellMoments<3>, cell, 0, 8);
COUPLER_WIRE_FIELD(CellMoments<3>, count, 8, 8);
COUPLER_WIRE_FIELD(CellMoments<3>, mass, 16, 8);
COUPLER_WIRE_FIELD(CellMoments<3>, first_moment_, 24, 24);
COUPLER_WIRE_FIELD(CellMoments<3>, momentum_, 48, 24);
COUPLER_WIRE_FIELD(CellMoments<3>, angular_, 72, 24);
COUPLER_WIRE_FIELD(CellMoments<3>, stress_volume_, 96, 72);

COUPLER_WIRE_SIZE(BodySums<3>, 384);
COUPLER_WIRE_FIELD(BodySums<3>, moments, 0, 168);
COUPLER_WIRE_FIELD(BodySums<3>, inertia_, 168, 72);
COUPLER_WIRE_FIELD(BodySums<3>, velocity_moment_, 240, 72);
COUPLER_WIRE_FIELD(BodySums<3>, position_moment_, 312, 72);

COUPLER_WIRE_SIZE(RezoneCell<3>, 272);
COUPLER_WIRE_FIELD(RezoneCell<3>, cell, 0, 8);
COUPLER_WIRE_FIELD(RezoneCell<3>, zone, 8, 4);
COUPLER_WIRE_FIELD(RezoneCell<3>, make_grains, 12, 4);
COUPLER_WIRE_FIELD(RezoneCell<3>, points, 16, 168);
COUPLER_WIRE_FIELD(RezoneCell<3>, gradient, 184, 72);
COUPLER_WIRE_FIELD(RezoneCell<3>, occupancy, 256, 8);
COUPLER_WIRE_FIELD(RezoneCell<3>, grain_weight, 264, 8);

COUPLER_WIRE_SIZE(GrainSums<3>, 768);
COUPLER_WIRE_FIELD(GrainSums<3>, carried, 0, 384);
COUPLER_WIRE_FIELD(GrainSums<3>, solid, 384, 384);

COUPLER_WIRE_SIZE(GrainCorrection<3>, 104);
COUPLER_WIRE_FIELD(GrainCorrection<3>, cell, 0, 8);
COUPLER_WIRE_FIELD(GrainCorrection<3>, remove, 8, 4);
COUPLER_WIRE_FIELD(GrainCorrection<3>, mechanism, 12, 4);
COUPLER_WIRE_FIELD(GrainCorrection<3>, weight, 16, 8);
COUPLER_WIRE_FIELD(GrainCorrection<3>, mass_factor, 24, 8);
COUPLER_WIRE_FIELD(GrainCorrection<3>, velocity, 32, 24);
COUPLER_WIRE_FIELD(GrainCorrection<3>, omega, 56, 24);
COUPLER_WIRE_FIELD(GrainCorrection<3>, centre, 80, 24);

#undef COUPLER_WIRE_FIELD
#undef COUPLER_WIRE_SIZE

}  // namespace coupler::wire_layout
