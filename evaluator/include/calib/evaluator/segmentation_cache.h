#pragma once
// On-disk cache of a recording's segmentation: one file per key.
//
// File layout (little-endian, as written by this machine):
//   char[8]  magic "CALIBSEG"
//   uint32   version (kSegmentationCacheVersion)
//   uint64   key
//   int32    width, height, origin_x, origin_y, words_per_row
//   uint32   num_frames
//   uint64   words[num_frames * height * words_per_row]   (BitMask::words())
//   uint64   FNV-1a 64 of the words' bytes
// A file whose size, magic, version, key, dimensions or checksum do not
// match is treated as absent.

#include "calib/evaluator/bit_mask.h"

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace calib {

inline constexpr uint32_t kSegmentationCacheVersion = 1;

/// 64-bit FNV-1a hash of `size` bytes, continuing from `hash`.
uint64_t Fnv1a64(const void* data, size_t size, uint64_t hash = 0xcbf29ce484222325ull);
inline uint64_t Fnv1a64(std::string_view s, uint64_t hash = 0xcbf29ce484222325ull) {
  return Fnv1a64(s.data(), s.size(), hash);
}

/// FNV-1a 64 of the bytes of a file, continuing from `hash`. Throws
/// std::runtime_error when the file cannot be read.
uint64_t HashFileContent(const std::filesystem::path& file, uint64_t hash = 0xcbf29ce484222325ull);

/// The cache file name of `key` in `dir`.
std::filesystem::path SegmentationCachePath(const std::filesystem::path& dir, uint64_t key);

/// Reads `num_frames` masks, each `width` x `height` at (origin_x, origin_y),
/// stored under `key`. False (and `masks` untouched) when the file is
/// missing, unreadable, truncated, corrupt or written for other dimensions.
bool ReadSegmentationCache(const std::filesystem::path& file, uint64_t key, int num_frames,
                           int width, int height, int origin_x, int origin_y,
                           std::vector<BitMask>* masks);

/// ReadSegmentationCache on the file's bytes in memory (tests, fuzz/).
bool DecodeSegmentationCache(std::string_view bytes, uint64_t key, int num_frames, int width,
                             int height, int origin_x, int origin_y, std::vector<BitMask>* masks);

/// Writes `masks` (all of one shape) under `key` atomically: to a temporary
/// file in the same folder, then renamed over `file`; creates the folder.
/// False when it could not be written (the cache is then left as it was).
bool WriteSegmentationCache(const std::filesystem::path& file, uint64_t key,
                            const std::vector<BitMask>& masks);

}  // namespace calib
