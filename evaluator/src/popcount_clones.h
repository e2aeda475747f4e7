#pragma once
// CALIB_POPCOUNT_CLONES: a function whose loop counts bits by words.
//
// The default x86-64 target has no popcount instruction, and the software
// fallback (libgcc's __popcountdi2, a call per word) makes a bit-mask
// comparison several times slower than the rasteriser. Without touching the
// project's flags, GCC/Clang compile such a function twice and pick the
// popcnt version at load time where the CPU has it; the counts are the same
// integers either way. (Not under ThreadSanitizer: see
// core/src/constraints.cpp.)

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__POPCNT__) && \
    !defined(__SANITIZE_THREAD__)
#define CALIB_POPCOUNT_CLONES __attribute__((target_clones("popcnt", "default")))
#else
#define CALIB_POPCOUNT_CLONES
#endif
