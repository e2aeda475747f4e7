#pragma once
// Conversions between BitMask and OpenCV 8-bit images.

#include "calib/evaluator/bit_mask.h"

#include <opencv2/core.hpp>

namespace calib {

/// A CV_8UC1 image of mask.height() rows by mask.width() columns: 255 where
/// the mask is on, 0 elsewhere. The origin is not represented.
cv::Mat ToMat(const BitMask& mask);

/// The mask of the non-zero pixels of `m8u` (CV_8UC1, any size), with pixel
/// (0, 0) at frame pixel (origin_x, origin_y). Throws std::invalid_argument
/// for an image of another type.
BitMask FromMat(const cv::Mat& m8u, int origin_x, int origin_y);

}  // namespace calib
