#pragma once
// Counts the heap allocations of a test program, for tests that a hot path
// allocates nothing in steady state. A program that includes this header
// compiles support/allocation_counter.cpp too (tests/CMakeLists.txt), which
// replaces the global operator new for the whole program.

#include <atomic>
#include <cstdint>

namespace calib::testing {

/// Allocations through the global operator new since the program started.
extern std::atomic<int64_t> g_allocations;

inline int64_t Allocations() { return g_allocations.load(); }

}  // namespace calib::testing
