#pragma once
// The MPM side of a coupled run: `mpm_solver --coupled`, started in the same MPMD mpirun as
// the DEM host: LAMMPS (lmp_hybrid, or a PLUGIN-enabled lmp with -mpicolor 0 and the
// hybridmpmplugin) or LIGGGHTS (liggghts_hybrid).
// Phase 1: handshake, per-step acknowledgements, clean finish; no continuum yet.
#include <exception>
#include <string>

namespace mpm {

/// What a caught exception was, as one sentence for the log and the DEM side: a UserError's own
/// text, else its message followed by its (demangled) type; unknown types are named as such.
std::string describe_exception(const std::exception_ptr& error);

struct CoupledOptions {
  /// Seconds to wait for the handshake (Hello) from fix hybrid/mpm: the DEM host sends it at the
  /// first run that uses the fix, after reading its input up to there. <= 0: forever.
  double hello_timeout = 600;
  bool quiet = false;
};

/// Initialises MPI, splits MPI_COMM_WORLD with coupler::kMpmColor, connects to the DEM side
/// and serves it until Finish. Returns the process exit status:
///   0 the DEM side finished the coupled run normally;
///   1 the DEM side stopped on an error or ended without connecting (its reason is printed);
///   2 the handshake was refused (version mismatch, bad parameters), no DEM side exists, or the
///     continuum failed (any exception, UserError or not: its cause is printed and sent to every
///     DEM rank as an error acknowledgement, so the DEM host stops at once naming it).
/// A DEM side that does not answer in time makes it print the cause and MPI_Abort the job,
/// since MPI_Finalize would wait for a hung peer forever.
int run_coupled(const CoupledOptions& options);

}  // namespace mpm
