// A small portable random generator: xoshiro256** seeded through splitmix64,
// with the uniform and normal transforms written out here, so the same seed
// gives the same numbers with any compiler and standard library (std::
// distributions differ between libraries). The full state, including the
// spare normal deviate of the polar method, saves to JSON and restores
// exactly.
#pragma once

#include <array>
#include <cstdint>

#include <nlohmann/json.hpp>

namespace calib::search {

class Rng {
 public:
  explicit Rng(uint64_t seed = 0);

  // xoshiro256** (Blackman & Vigna 2018): 64 random bits.
  uint64_t NextU64();
  // Uniform on [0, 1) with 53 random bits.
  double Uniform01();
  // Uniform on [a, b).
  double Uniform(double a, double b);
  // Uniform integer in [0, n), n >= 1, without modulo bias (rejection).
  uint64_t UniformInt(uint64_t n);
  // Standard normal N(0, 1) by Marsaglia's polar method; the second deviate
  // of each pair is kept for the next call (and saved with the state).
  double Normal();

  nlohmann::json Save() const;
  // Throws std::invalid_argument when the JSON is not a saved Rng state.
  void Restore(const nlohmann::json& state);

  bool operator==(const Rng&) const = default;

 private:
  std::array<uint64_t, 4> s_{};
  bool has_spare_ = false;
  double spare_ = 0.0;
};

// splitmix64 (Steele, Lea & Flood 2014): derives independent seeds, e.g. one
// per purpose inside an optimiser.
uint64_t SplitMix64(uint64_t& state);

}  // namespace calib::search
