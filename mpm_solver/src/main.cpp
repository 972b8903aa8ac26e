// mpm_solver: runs a pure-MPM scene from a TOML scene file, or (--coupled) serves as the
// continuum side of a coupled run with a DEM host, LAMMPS or LIGGGHTS (mpm/coupled.hpp).
#include <hdf5.h>
#include <mpi.h>
#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <string>

#include "coupler/version.hpp"
#include "mpm/config.hpp"
#include "mpm/coupled.hpp"
#include "mpm/solver.hpp"

namespace {

struct Options {
  std::string scene_path;
  std::string output_dir;
  int threads = 0;
  double end_time = 0;
  bool quiet = false;
  bool no_output = false;
  bool check_only = false;
  long max_steps = 0;
  std::string summary_path;
  bool coupled = false;
  double peer_timeout = 600;
};

/// Peak resident memory of this process, bytes.
long peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss * 1024L;
}

void print_progress(const mpm::RunProgress& p) {
  std::printf("step %8ld  t = %10.5f s  dt = %9.3e s  wall = %8.1f s  %7.2f M point-steps/s\n", p.step, p.time, p.dt,
              p.wall_seconds, p.point_steps_per_second * 1e-6);
  std::fflush(stdout);
}

template <int D>
int run_scene(const mpm::Scene& scene, const Options& opt) {
  mpm::Solver<D> solver(scene);
  std::printf("mpm_solver %s: %dD, %zu material points, %zu grid nodes (dx = %g m), %d thread(s), stable dt = %.3e s\n",
              coupler::release_version(), D, solver.points().size(), solver.grid().num_nodes(), solver.grid().dx,
              omp_get_max_threads(), solver.stable_dt());
  if (opt.check_only) return 0;
  std::function<void(const mpm::RunProgress&)> progress;
  if (!opt.quiet) progress = print_progress;
  const mpm::RunProgress done = mpm::run(solver, {!opt.no_output, opt.max_steps}, progress);
  if (!opt.summary_path.empty()) {
    // Machine-readable figures for benchmarks and scripts.
    std::ofstream out(opt.summary_path);
    out.precision(17);    // the outflow is summed against the points' masses to round-off
    out << "{\"dimension\": " << D << ", \"points\": " << solver.points().size()
        << ", \"grid_nodes\": " << solver.grid().num_nodes() << ", \"threads\": " << omp_get_max_threads()
        << ", \"steps\": " << done.step << ", \"time\": " << done.time << ", \"wall_seconds\": " << done.wall_seconds
        << ", \"point_steps_per_second\": " << done.point_steps_per_second
        << ", \"peak_rss_bytes\": " << peak_rss_bytes();
    if (!scene.outlets.empty())
      out << ", \"outflow_mass\": " << solver.outflow_mass() << ", \"outflow_points\": " << solver.outflow_points();
    out << "}\n";
    if (!out) throw mpm::UserError("cannot write the summary file " + opt.summary_path);
  }
  if (!opt.no_output) std::printf("output: %s/points.h5 and points.xdmf\n", scene.output.directory.c_str());
  return 0;
}

/// In a coupled run the MPM process and the LAMMPS ranks take turns on the same cores: LAMMPS
/// waits while the MPM works and the other way round. OpenMP's default after a parallel region
/// is to keep its threads spinning for a while (libgomp: about 300,000 polls, longer than an
/// exchange interval), and those threads then take the cores from LAMMPS's steps: measured on
/// the 80k-disk silo (2 ranks + 2 threads on 2 cores), a LAMMPS chunk took 6.6 s with the MPM
/// threaded against 3.4 s with it on one thread. The wait policy is read when the OpenMP runtime
/// loads, before main, so a coupled process that has none set starts itself again with
/// OMP_WAIT_POLICY=passive (its threads sleep when idle). Returns only if that is not needed or
/// the restart failed (the run goes on, slower).
void restart_with_passive_openmp_threads(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr || omp_get_max_threads() == 1) return;
  // The program's own path, not /proc/self/exe, so that the process keeps its name (ps, pgrep).
  char path[4096];
  const ssize_t n = readlink("/proc/self/exe", path, sizeof(path) - 1);
  if (n > 0 && setenv("OMP_WAIT_POLICY", "passive", 1) == 0) {
    path[n] = '\0';
    execv(path, argv);
  }
  std::fprintf(stderr, "mpm_solver: warning: could not restart with OMP_WAIT_POLICY=passive (%s); set it in the "
               "environment of the MPM process, or its idle threads will take cores from LAMMPS\n",
               std::strerror(errno));
}

}  // namespace

int main(int argc, char** argv) {
  // Every HDF5 file is closed by its owner (RAII) before main returns, so HDF5's own clean-up has
  // nothing to do - except after a failed write (a full disk): such a file cannot be closed, and
  // HDF5's clean-up of it crashed the process (segfault in H5F__close_cb) after the error had been
  // reported. HDF5 runs that clean-up at exit and, if MPI is up when the library starts, in
  // MPI_Finalize (an MPI_COMM_SELF attribute): so no atexit handler, and the library is started
  // here, before --coupled initialises MPI. The files use HDF5's default (POSIX) driver, not MPI-IO.
  H5dont_atexit();
  H5open();
  CLI::App app{"mpm_solver: explicit material point method for dry granular continua (2D and 3D)"};
  Options opt;
  app.add_option("scene", opt.scene_path, "scene file (TOML); keys are listed below (not with --coupled)")
      ->check(CLI::ExistingFile);
  app.add_option("-o,--output", opt.output_dir, "output directory (overrides [output] directory)");
  app.add_option("-t,--threads", opt.threads, "OpenMP threads (default: OMP_NUM_THREADS or all cores)")
      ->check(CLI::PositiveNumber);
  app.add_option("--end-time", opt.end_time, "simulated end time in s (overrides end_time)")->check(CLI::PositiveNumber);
  app.add_flag("-q,--quiet", opt.quiet, "no progress lines");
  app.add_flag("--no-output", opt.no_output, "write no snapshots (benchmarks)");
  app.add_option("--max-steps", opt.max_steps, "stop after this many steps (benchmarks)")->check(CLI::PositiveNumber);
  app.add_option("--summary", opt.summary_path, "write run figures (steps, wall time, rate, peak memory) as JSON");
  app.add_flag("--check", opt.check_only, "read the scene, seed it, print its size and stable step, and exit");
  auto* coupled = app.add_flag("--coupled", opt.coupled,
                               "continuum side of a coupled run with a DEM host (LAMMPS's lmp_hybrid or LIGGGHTS's "
                               "liggghts_hybrid): start in the same mpirun as it (tools/hybrid_launch.py); no scene "
                               "file; see docs/fix_hybrid_mpm.md");
  app.add_option("--timeout", opt.peer_timeout,
                 "with --coupled: seconds to wait for the handshake from fix hybrid/mpm (default 600; 0 = forever)")
      ->check(CLI::NonNegativeNumber)
      ->needs(coupled);
  app.set_version_flag("--version", std::string("mpm_solver ") + coupler::release_version());
  app.footer("\nSCENE FILE KEYS\n\n" + mpm::config_reference());
  CLI11_PARSE(app, argc, argv);

  if (opt.coupled) {
    if (!opt.scene_path.empty()) {
      std::fprintf(stderr, "mpm_solver: error: --coupled takes no scene file (got %s)\n", opt.scene_path.c_str());
      return 2;
    }
    restart_with_passive_openmp_threads(argv);
    mpm::CoupledOptions copt;
    copt.hello_timeout = opt.peer_timeout;
    copt.quiet = opt.quiet;
    // run_coupled reports its own failures; this is the last line of defence: a failure
    // escaping it must end the whole MPI job, since the DEM host would otherwise wait for its timeout.
    try {
      return mpm::run_coupled(copt);
    } catch (...) {
      const std::string what = mpm::describe_exception(std::current_exception());
      std::fprintf(stderr, "mpm_solver: internal error in the coupled run: %s; aborting the MPI job\n", what.c_str());
      std::fflush(stderr);
      int initialized = 0, finalized = 0;
      MPI_Initialized(&initialized);
      MPI_Finalized(&finalized);
      if (initialized && !finalized) MPI_Abort(MPI_COMM_WORLD, 3);
      return 3;
    }
  }
  if (opt.scene_path.empty()) {
    std::fprintf(stderr, "mpm_solver: error: a scene file is required (or --coupled)\nRun with --help for more information.\n");
    return 106;  // CLI11's exit code for a missing required argument, as before
  }
  // Started by mpirun next to other programs without --coupled: they would wait for this
  // process in MPI_Comm_split forever, so refuse loudly (mpirun then stops the job).
  if (const char* apps = std::getenv("OMPI_NUM_APP_CTX"); apps != nullptr && std::atoi(apps) > 1) {
    std::fprintf(stderr,
                 "mpm_solver: error: started by mpirun in an MPMD job (%s programs) but without --coupled; "
                 "tools/hybrid_launch.py composes the command\n",
                 apps);
    return 2;
  }

  try {
    mpm::Scene scene = mpm::load_scene(opt.scene_path);
    if (!opt.output_dir.empty()) scene.output.directory = opt.output_dir;
    if (opt.end_time > 0) scene.time.end_time = opt.end_time;
    if (opt.threads > 0) omp_set_num_threads(opt.threads);
    return scene.dimension == 2 ? run_scene<2>(scene, opt) : run_scene<3>(scene, opt);
  } catch (const mpm::UserError& e) {
    std::fprintf(stderr, "mpm_solver: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mpm_solver: internal error: %s\n", e.what());
    return 3;
  }
}
