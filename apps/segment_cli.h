#pragma once
// `calib segment REC --preview`: the colour segmentation of chosen frames
// over the video (evaluator/segmentation_preview.h). Kept apart from
// calib_main.cpp so that each subcommand family owns its options.

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace calib::cli {

struct SegmentCli;

/// Adds `segment` to `app`; the returned object holds its options and must
/// outlive parsing.
std::shared_ptr<SegmentCli> AddSegmentSubcommand(CLI::App& app);

/// After parsing: when `segment` was chosen, does it and returns 0;
/// nullopt otherwise. Errors throw (the caller prints them, exit 2).
std::optional<int> RunChosenSegmentSubcommand(SegmentCli& cli);

}  // namespace calib::cli
