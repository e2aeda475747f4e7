#pragma once
// The service subcommands of calib: serve (the server), submit, status and
// cancel (its clients) and jobs (a store's jobs, or a server's). Kept apart
// from calib_main.cpp so that each subcommand family owns its options.

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace calib::cli {

struct ServiceCli;

/// Adds serve, submit, status, cancel and jobs to `app`; the returned object
/// holds their options and must outlive parsing.
std::shared_ptr<ServiceCli> AddServiceSubcommands(CLI::App& app);

/// After parsing: when one of them was chosen, does it and returns the exit
/// status; nullopt otherwise. Errors throw (the caller prints them, exit 2).
std::optional<int> RunChosenServiceSubcommand(ServiceCli& cli);

}  // namespace calib::cli
