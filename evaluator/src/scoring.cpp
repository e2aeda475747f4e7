#include "calib/evaluator/scoring.h"

#include "popcount_clones.h"

#include <bit>
#include <cstdio>
#include <cstdlib>

namespace calib {
namespace {

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

namespace {

void CheckSameShape(const BitMask& object, const BitMask& interior) {
  if (!object.SameShape(interior)) {
    std::fprintf(stderr,
                 "CompareCoverage: masks differ in shape: object %dx%d at (%d, %d), mesh %dx%d at "
                 "(%d, %d)\n",
                 object.width(), object.height(), object.origin_x(), object.origin_y(),
                 interior.width(), interior.height(), interior.origin_x(), interior.origin_y());
    std::abort();
  }
}

// The score from the interior's word counts `c` and the boundary pixels.
FrameScore Finish(const BitMask& object, const WordCounts& c,
                  std::span<const PixelCoverage> boundary) {
  double covered_object = 0.0;  // coverage summed over boundary pixels of the object
  double covered_other = 0.0;   // and over the others
  for (const PixelCoverage& p : boundary) {
    (object.Get(p.x, p.y) ? covered_object : covered_other) += p.coverage;
  }
  FrameScore s;
  s.missed_px = static_cast<double>(c.missed) - covered_object;
  s.extra_px = static_cast<double>(c.extra) + covered_other;
  s.xor_px = s.missed_px + s.extra_px;
  s.object_px = static_cast<double>(c.missed + c.both);
  s.mesh_px = static_cast<double>(c.extra + c.both) + (covered_object + covered_other);
  const double both = static_cast<double>(c.both) + covered_object;
  const double union_px = s.object_px + s.mesh_px - both;
  s.iou = union_px == 0.0 ? 1.0 : both / union_px;
  return s;
}

}  // namespace

FrameScore CompareCoverage(const BitMask& object, const BitMask& interior,
                           std::span<const PixelCoverage> boundary) {
  CheckSameShape(object, interior);
  // Unused high bits of each row's last word are 0 in both masks, so whole
  // words can be counted. Boundary pixels are not in `interior`: counted
  // here as mesh-free, corrected by their coverage (Finish).
  return Finish(object,
                CountWords(object.words().data(), interior.words().data(), object.words().size()),
                boundary);
}

FrameScore CompareCoverageInRows(const BitMask& object, int64_t object_px,
                                 const BitMask& interior, int row_begin, int row_end,
                                 std::span<const PixelCoverage> boundary) {
  CheckSameShape(object, interior);
  if (row_begin >= row_end) row_begin = row_end = 0;
  const size_t first = static_cast<size_t>(row_begin) * interior.words_per_row();
  const size_t count = static_cast<size_t>(row_end - row_begin) * interior.words_per_row();
  WordCounts c = CountWords(object.words().data() + first, interior.words().data() + first, count);
  // Outside the rows the mesh has no pixel: every object pixel there is
  // missed, so missed + both is the object's count.
  c.missed = object_px - c.both;
  return Finish(object, c, boundary);
}

FrameScore CompareMasks(const BitMask& object, const BitMask& mesh) {
  return CompareCoverage(object, mesh, {});
}

}  // namespace calib
