#include "calib/evaluator/bit_mask_cv.h"

#include <stdexcept>

namespace calib {

cv::Mat ToMat(const BitMask& mask) {
  cv::Mat out(mask.height(), mask.width(), CV_8UC1);
  for (int y = 0; y < mask.height(); ++y) {
    const uint64_t* words = mask.Row(y);
    uint8_t* row = out.ptr<uint8_t>(y);
    for (int x = 0; x < mask.width(); ++x) {
      row[x] = ((words[x >> 6] >> (x & 63)) & 1u) ? 255 : 0;
    }
  }
  return out;
}

BitMask FromMat(const cv::Mat& m8u, int origin_x, int origin_y) {
  if (m8u.type() != CV_8UC1) {
    throw std::invalid_argument("FromMat: expected a CV_8UC1 image, found type " +
                                std::to_string(m8u.type()));
  }
  BitMask mask(m8u.cols, m8u.rows, origin_x, origin_y);
  for (int y = 0; y < m8u.rows; ++y) {
    const uint8_t* row = m8u.ptr<uint8_t>(y);
    uint64_t* words = mask.Row(y);
    for (int x = 0; x < m8u.cols; ++x) {
      if (row[x] != 0) words[x >> 6] |= uint64_t{1} << (x & 63);
    }
  }
  return mask;
}

}  // namespace calib
