// Fuzz target: segmentation cache files (DecodeSegmentationCache, the
// reader behind ReadSegmentationCache; segmentation_cache.h has the layout).
// The first 4 bytes are what the caller expects: frames (byte 0 % 4), width
// (byte 1 % 130), height (byte 2 % 9), origin x = origin y (byte 3, signed);
// the key is fixed. The rest is the file. Expected: true with masks of that
// shape, or false; the reader throws nothing.

#include "calib/evaluator/segmentation_cache.h"
#include "fuzz_support.h"

#include <cstdio>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  if (size < 4) return 0;
  const int frames = data[0] % 4;
  const int width = data[1] % 130;
  const int height = data[2] % 9;
  const int origin = static_cast<int8_t>(data[3]);
  constexpr uint64_t kKey = 0x0123456789abcdefull;
  std::vector<BitMask> masks;
  bool ok = false;
  try {
    ok = DecodeSegmentationCache(fuzz::Text(data + 4, size - 4), kKey, frames, width, height,
                                 origin, origin, &masks);
  } catch (...) {
    fuzz::Unexpected("fuzz_segmentation_cache");
  }
  if (!ok) return 0;
  bool shape_ok = static_cast<int>(masks.size()) == frames;
  for (const BitMask& m : masks) {
    shape_ok = shape_ok && m.width() == width && m.height() == height && m.origin_x() == origin &&
               m.origin_y() == origin;
  }
  if (!shape_ok) {
    std::fprintf(stderr, "fuzz_segmentation_cache: masks of the wrong shape\n");
    std::abort();
  }
  return 0;
}
