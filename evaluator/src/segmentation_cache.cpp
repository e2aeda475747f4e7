#include "calib/evaluator/segmentation_cache.h"

#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace calib {
namespace {

namespace fs = std::filesystem;

constexpr std::array<char, 8> kMagic{'C', 'A', 'L', 'I', 'B', 'S', 'E', 'G'};

struct Header {
  uint32_t version = 0;
  uint64_t key = 0;
  int32_t width = 0;
  int32_t height = 0;
  int32_t origin_x = 0;
  int32_t origin_y = 0;
  int32_t words_per_row = 0;
  uint32_t num_frames = 0;
};

// Header size on disk: magic + fields, packed.
constexpr size_t kHeaderBytes = 8 + 4 + 8 + 5 * 4 + 4;

template <class T>
void Put(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

template <class T>
T Take(const char** p) {
  T value;
  std::memcpy(&value, *p, sizeof(T));
  *p += sizeof(T);
  return value;
}

std::string EncodeHeader(const Header& h) {
  std::string out(kMagic.data(), kMagic.size());
  Put(&out, h.version);
  Put(&out, h.key);
  Put(&out, h.width);
  Put(&out, h.height);
  Put(&out, h.origin_x);
  Put(&out, h.origin_y);
  Put(&out, h.words_per_row);
  Put(&out, h.num_frames);
  return out;
}

/// A name for the temporary file that no other writer (thread or process)
/// uses at the same time.
fs::path TempPath(const fs::path& file) {
  static std::atomic<uint64_t> counter{0};
  const auto now = std::chrono::steady_clock::now().time_since_epoch().count();
  return fs::path(file.string() + ".tmp." + std::to_string(::getpid()) + "." +
                  std::to_string(counter++) + "." + std::to_string(now));
}

}  // namespace

uint64_t Fnv1a64(const void* data, size_t size, uint64_t hash) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) {
    hash ^= bytes[i];
    hash *= 0x100000001b3ull;
  }
  return hash;
}

uint64_t HashFileContent(const fs::path& file, uint64_t hash) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot open file");
  std::array<char, 1 << 16> buffer;
  while (in) {
    in.read(buffer.data(), buffer.size());
    hash = Fnv1a64(buffer.data(), static_cast<size_t>(in.gcount()), hash);
  }
  if (in.bad()) throw std::runtime_error(file.string() + ": read error");
  return hash;
}

fs::path SegmentationCachePath(const fs::path& dir, uint64_t key) {
  char name[32];
  std::snprintf(name, sizeof(name), "%016llx.segcache", static_cast<unsigned long long>(key));
  return dir / name;
}

namespace {

/// The size of a cache file of these dimensions; 0 for dimensions no file
/// can have.
uint64_t ExpectedBytes(int num_frames, int width, int height) {
  if (num_frames < 0 || width < 0 || height < 0) return 0;
  const uint64_t words_per_mask = (static_cast<uint64_t>(width) + 63) / 64 * height;
  return kHeaderBytes + (words_per_mask * num_frames + 1) * sizeof(uint64_t);
}

}  // namespace

bool ReadSegmentationCache(const fs::path& file, uint64_t key, int num_frames, int width,
                           int height, int origin_x, int origin_y, std::vector<BitMask>* masks) {
  const uint64_t expected_bytes = ExpectedBytes(num_frames, width, height);
  if (expected_bytes == 0) return false;
  std::error_code ec;
  const uint64_t size = fs::file_size(file, ec);
  if (ec || size != expected_bytes) return false;
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::string bytes(expected_bytes, '\0');
  if (!in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()))) return false;
  return DecodeSegmentationCache(bytes, key, num_frames, width, height, origin_x, origin_y, masks);
}

bool DecodeSegmentationCache(std::string_view bytes, uint64_t key, int num_frames, int width,
                             int height, int origin_x, int origin_y, std::vector<BitMask>* masks) {
  const uint64_t expected_bytes = ExpectedBytes(num_frames, width, height);
  if (expected_bytes == 0 || bytes.size() != expected_bytes) return false;
  const int words_per_row = (width + 63) / 64;
  const uint64_t words_per_mask = static_cast<uint64_t>(words_per_row) * height;

  Header expected;
  expected.version = kSegmentationCacheVersion;
  expected.key = key;
  expected.width = width;
  expected.height = height;
  expected.origin_x = origin_x;
  expected.origin_y = origin_y;
  expected.words_per_row = words_per_row;
  expected.num_frames = static_cast<uint32_t>(num_frames);
  if (bytes.compare(0, kHeaderBytes, EncodeHeader(expected)) != 0) return false;

  const char* words = bytes.data() + kHeaderBytes;
  const size_t words_bytes = words_per_mask * num_frames * sizeof(uint64_t);
  const char* tail = words + words_bytes;
  if (Take<uint64_t>(&tail) != Fnv1a64(words, words_bytes)) return false;

  // Bits beyond a row's width must be zero (a BitMask invariant).
  const int spare = words_per_row * 64 - width;
  const uint64_t spare_bits = spare == 0 ? 0 : ~uint64_t{0} << (64 - spare);
  std::vector<BitMask> out;
  out.reserve(num_frames);
  for (int f = 0; f < num_frames; ++f) {
    BitMask mask(width, height, origin_x, origin_y);
    std::memcpy(mask.words().data(), words + f * words_per_mask * sizeof(uint64_t),
                words_per_mask * sizeof(uint64_t));
    for (int y = 0; spare_bits != 0 && y < height; ++y) {
      if (mask.Row(y)[words_per_row - 1] & spare_bits) return false;
    }
    out.push_back(std::move(mask));
  }
  *masks = std::move(out);
  return true;
}

bool WriteSegmentationCache(const fs::path& file, uint64_t key, const std::vector<BitMask>& masks) {
  Header h;
  h.version = kSegmentationCacheVersion;
  h.key = key;
  h.num_frames = static_cast<uint32_t>(masks.size());
  if (!masks.empty()) {
    h.width = masks.front().width();
    h.height = masks.front().height();
    h.origin_x = masks.front().origin_x();
    h.origin_y = masks.front().origin_y();
    h.words_per_row = masks.front().words_per_row();
  }
  std::string words;
  words.reserve(masks.empty() ? 0 : masks.size() * masks.front().words().size() * 8);
  for (const BitMask& m : masks) {
    if (!m.SameShape(masks.front())) return false;
    words.append(reinterpret_cast<const char*>(m.words().data()), m.words().size() * 8);
  }

  std::error_code ec;
  if (file.has_parent_path()) fs::create_directories(file.parent_path(), ec);
  if (ec) return false;
  const fs::path temp = TempPath(file);
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) return false;
    const std::string header = EncodeHeader(h);
    std::string checksum;
    Put(&checksum, Fnv1a64(words.data(), words.size()));
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.write(words.data(), static_cast<std::streamsize>(words.size()));
    out.write(checksum.data(), static_cast<std::streamsize>(checksum.size()));
    out.close();
    if (!out) {
      fs::remove(temp, ec);
      return false;
    }
  }
  fs::rename(temp, file, ec);
  if (ec) {
    fs::remove(temp, ec);
    return false;
  }
  return true;
}

}  // namespace calib
