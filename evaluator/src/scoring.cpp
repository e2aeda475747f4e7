#include "calib/evaluator/scoring.h"

#include <bit>
#include <cstdio>
#include <cstdlib>

namespace calib {
namespace {

// The default x86-64 target has no popcount instruction, and the software
// fallback makes the comparison several times slower than the rasteriser.
// Without touching the project's flags, GCC/Clang compile this loop twice and
// pick the popcnt version at load time where the CPU has it.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__POPCNT__)
#define CALIB_POPCOUNT_CLONES __attribute__((target_clones("popcnt", "default")))
#else
#define CALIB_POPCOUNT_CLONES
#endif

struct WordCounts {
  int64_t missed = 0;
  int64_t extra = 0;
  int64_t both = 0;
};

CALIB_POPCOUNT_CLONES
WordCounts CountWords(const uint64_t* o, const uint64_t* m, size_t n) {
  WordCounts c;
  for (size_t i = 0; i < n; ++i) {
    c.missed += std::popcount(o[i] & ~m[i]);
    c.extra += std::popcount(m[i] & ~o[i]);
    c.both += std::popcount(o[i] & m[i]);
  }
  return c;
}

}  // namespace

FrameScore CompareMasks(const BitMask& object, const BitMask& mesh) {
  if (!object.SameShape(mesh)) {
    std::fprintf(stderr,
                 "CompareMasks: masks differ in shape: object %dx%d at (%d, %d), mesh %dx%d at "
                 "(%d, %d)\n",
                 object.width(), object.height(), object.origin_x(), object.origin_y(),
                 mesh.width(), mesh.height(), mesh.origin_x(), mesh.origin_y());
    std::abort();
  }
  // Unused high bits of each row's last word are 0 in both masks, so whole
  // words can be counted.
  const WordCounts c =
      CountWords(object.words().data(), mesh.words().data(), object.words().size());
  FrameScore s;
  s.missed_px = c.missed;
  s.extra_px = c.extra;
  s.xor_px = c.missed + c.extra;
  s.object_px = c.missed + c.both;
  s.mesh_px = c.extra + c.both;
  const int64_t union_px = c.missed + c.extra + c.both;
  s.iou = union_px == 0 ? 1.0 : static_cast<double>(c.both) / static_cast<double>(union_px);
  return s;
}

}  // namespace calib
