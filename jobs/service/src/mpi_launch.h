#pragma once
// A queued calibration job run on MPI ranks over several hosts
// (ServiceOptions::mpi_hosts): the service starts scripts/calib-mpirun.sh
// (rank 0 the manager on the first host, a worker rank on every other slot;
// a host that dies is dropped and the job resumed on the others) on the job's
// spec file, as `calib run` / `calib resume` would run it. The service's
// private helper (queued_work.cpp).
//
// The launcher is the server's child: `interrupted` sends it SIGTERM, which
// it passes on (the manager stops resumably, exit 4); should the server die,
// the kernel sends it SIGTERM too (PR_SET_PDEATHSIG), so no job runs on
// without a server to follow it.

#include "calib/service/job_service.h"

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace calib::service {

/// Runs `calib_args` (after the spec) of the job spec `spec_file` (with
/// `comparison`, the optimiser comparison spec: the launcher's --compare)
/// through the launcher; its output goes to `log_file`. Returns the launcher's exit
/// status (0 finished, 3 aborted by the failure policy, 4 stopped
/// resumably); throws std::runtime_error naming the launcher and the log for
/// any other, or when it cannot be started.
int RunOnMpiHosts(const ServiceOptions& options, const std::filesystem::path& spec_file,
                  const std::vector<std::string>& calib_args, const std::filesystem::path& log_file,
                  const std::function<bool()>& interrupted, bool comparison = false);

}  // namespace calib::service
