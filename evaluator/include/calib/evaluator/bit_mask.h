#pragma once
// A binary image packed 64 pixels to a word, row by row. Pixel (x, y) of the
// mask is pixel (origin_x + x, origin_y + y) of the video frame; a pixel is
// "on" when its centre (x + 0.5, y + 0.5) lies inside the shape (the same
// convention for segmented object masks and rasterised meshes).

#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

namespace calib {

class BitMask {
 public:
  BitMask() = default;
  BitMask(int width, int height, int origin_x = 0, int origin_y = 0)
      : width_(width),
        height_(height),
        origin_x_(origin_x),
        origin_y_(origin_y),
        words_per_row_((width + 63) / 64),
        words_(static_cast<size_t>(words_per_row_) * height, 0) {}

  int width() const { return width_; }
  int height() const { return height_; }
  int origin_x() const { return origin_x_; }
  int origin_y() const { return origin_y_; }
  int words_per_row() const { return words_per_row_; }

  bool Get(int x, int y) const {
    return (words_[Index(y) + (x >> 6)] >> (x & 63)) & 1u;
  }
  void Set(int x, int y, bool on = true) {
    uint64_t& w = words_[Index(y) + (x >> 6)];
    const uint64_t bit = uint64_t{1} << (x & 63);
    w = on ? (w | bit) : (w & ~bit);
  }
  /// Sets pixels [x0, x1) of row y; clips to the mask.
  void SetSpan(int y, int x0, int x1) {
    if (y < 0 || y >= height_) return;
    if (x0 < 0) x0 = 0;
    if (x1 > width_) x1 = width_;
    if (x0 >= x1) return;
    uint64_t* row = words_.data() + Index(y);
    const int w0 = x0 >> 6, w1 = (x1 - 1) >> 6;
    const uint64_t first = ~uint64_t{0} << (x0 & 63);
    const uint64_t last = ~uint64_t{0} >> (63 - ((x1 - 1) & 63));
    if (w0 == w1) {
      row[w0] |= first & last;
      return;
    }
    row[w0] |= first;
    for (int w = w0 + 1; w < w1; ++w) row[w] = ~uint64_t{0};
    row[w1] |= last;
  }
  void Clear() { std::fill(words_.begin(), words_.end(), 0); }

  int64_t Count() const {
    int64_t n = 0;
    for (uint64_t w : words_) n += std::popcount(w);
    return n;
  }

  const uint64_t* Row(int y) const { return words_.data() + Index(y); }
  uint64_t* Row(int y) { return words_.data() + Index(y); }
  const std::vector<uint64_t>& words() const { return words_; }
  std::vector<uint64_t>& words() { return words_; }

  bool SameShape(const BitMask& o) const {
    return width_ == o.width_ && height_ == o.height_ && origin_x_ == o.origin_x_ &&
           origin_y_ == o.origin_y_;
  }
  bool operator==(const BitMask& o) const { return SameShape(o) && words_ == o.words_; }

 private:
  size_t Index(int y) const { return static_cast<size_t>(y) * words_per_row_; }

  int width_ = 0;
  int height_ = 0;
  int origin_x_ = 0;
  int origin_y_ = 0;
  int words_per_row_ = 0;
  std::vector<uint64_t> words_;  // unused high bits of a row's last word stay 0
};

}  // namespace calib
