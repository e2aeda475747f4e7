#include "calib/search/rng.h"

#include "state_util.h"

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace calib::search {

uint64_t SplitMix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

Rng::Rng(uint64_t seed) {
  uint64_t sm = seed;
  for (auto& word : s_) word = SplitMix64(sm);
}

namespace {
inline uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
}  // namespace

uint64_t Rng::NextU64() {
  const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
  const uint64_t t = s_[1] << 17;
  s_[2] ^= s_[0];
  s_[3] ^= s_[1];
  s_[1] ^= s_[2];
  s_[0] ^= s_[3];
  s_[2] ^= t;
  s_[3] = Rotl(s_[3], 45);
  return result;
}

double Rng::Uniform01() { return static_cast<double>(NextU64() >> 11) * 0x1.0p-53; }

double Rng::Uniform(double a, double b) { return a + (b - a) * Uniform01(); }

uint64_t Rng::UniformInt(uint64_t n) {
  if (n == 0) throw std::invalid_argument("Rng::UniformInt: n = 0. Violated: n >= 1");
  // Reject the top partial copy of [0, n) so every residue is equally likely.
  const uint64_t limit = UINT64_MAX - UINT64_MAX % n;
  uint64_t r;
  do {
    r = NextU64();
  } while (r >= limit);
  return r % n;
}

double Rng::Normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  double u, v, s;
  do {
    u = 2.0 * Uniform01() - 1.0;
    v = 2.0 * Uniform01() - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double factor = std::sqrt(-2.0 * std::log(s) / s);
  spare_ = v * factor;
  has_spare_ = true;
  return u * factor;
}

nlohmann::json Rng::Save() const {
  // The spare is stored as its bit pattern so it round-trips exactly.
  uint64_t spare_bits;
  static_assert(sizeof(spare_bits) == sizeof(spare_));
  std::memcpy(&spare_bits, &spare_, sizeof(spare_bits));
  return {{"xoshiro256", {s_[0], s_[1], s_[2], s_[3]}},
          {"has_spare", has_spare_},
          {"spare_bits", spare_bits}};
}

void Rng::Restore(const nlohmann::json& state) {
  if (!state.is_object() || !state.contains("xoshiro256") || !state["xoshiro256"].is_array() ||
      state["xoshiro256"].size() != 4) {
    throw std::invalid_argument("Rng state: expected {\"xoshiro256\": [4 integers], ...}, found " +
                                state.dump());
  }
  for (int i = 0; i < 4; ++i) {
    s_[i] = internal::IntFromJson<uint64_t>(state["xoshiro256"][i], "xoshiro256");
  }
  has_spare_ = state.at("has_spare").get<bool>();
  const auto spare_bits = internal::IntFromJson<uint64_t>(state.at("spare_bits"), "spare_bits");
  std::memcpy(&spare_, &spare_bits, sizeof(spare_));
}

}  // namespace calib::search
