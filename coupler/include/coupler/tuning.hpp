#pragma once
// Tuned constants of the coupling, each defined here once with the reason for its value
// (measurements in docs/design.md, section 5). Changing one changes results.

namespace coupler {

/// A grain made from points (enrichment, design.md 5.6) that an old grain overlaps by more than
/// 1 - this share of its radius is dropped (an overlap would inject elastic energy); one
/// overlapped less is pushed off by at most that much, keeping its size, and shrinks to fit, down
/// to this share of its radius, only where the pushes leave it overlapped. Dropping every
/// overlapped candidate left gaps along the old packing; 0.8 closes them (set with the handoff
/// cycle of tests/test_adaptive_zones.py, not tuned further).
inline constexpr double kSmallestShrink = 0.8;

/// The smallest MPM cell adaptive zones accept, in mean grain diameters: with cells under 2 d the
/// oracle's packing fraction per cell counts one or two grains and a cell's rests land on a few
/// points (a published 2D collapse with 1.74 d cells went non-finite as its continuum shrank,
/// issue 14, while the same scene ran with 5 d cells).
inline constexpr double kSmallestCellInGrains = 2.0;

/// The least number of grains a material point made from grains should carry when the fix line
/// leaves the grid to the grains (no `cell`): the continuum pays off only where it is much coarser
/// than the grains it replaces (issue 15: at 1.3 grains per point a 15,000-disk silo's continuum
/// cost almost what its grains did). With 2 points per cell and axis this gives cells of 6 d in 2D
/// and 4 d in 3D (docs/design.md section 5.1).
inline constexpr double kGrainsPerPoint = 8.0;

/// Points per cell and axis when the fix line gives none: 2 is the usual quadrature of MPM with
/// quadratic B-splines (one point per cell and axis leaves cells empty as the material shears).
inline constexpr int kPointsPerAxis = 2;

/// The speed below which the zone oracle takes a cell's material for at rest and holds its zone
/// (hold_zones_at_rest), in units of sqrt(g d) (g gravity, d the mean grain diameter): 0.01, a
/// kinetic energy per unit mass of 5e-5 g d, five times the decks' rest criterion on the mean
/// kinetic energy per grain (1e-5 m g d), so that a deposit's cells are held before the whole
/// material counts as at rest, while a flowing silo or collapse (0.1-1 sqrt(g d)) is never held.
inline constexpr double kRestSpeed = 0.01;

/// The energy the coupling may make before the run stops (EnergyGuard), as a share of the scene's
/// energy scale M |g| h: on the deep 2D silo's runs (three packings, with and without the fill
/// pressure) the terms it watches rise at most 0.35 % of it above their lowest, and the one runaway
/// measured crossed 5 % 0.016 s after its start (bench/results/adaptive_accuracy.md).
inline constexpr double kEnergyGuard = 0.05;

}  // namespace coupler
