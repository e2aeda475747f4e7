// Internal: exact JSON encodings for optimiser state, and the box mapping.
// Doubles are stored as JSON numbers when finite (nlohmann writes 17
// significant digits, so dump/parse round-trips bit for bit) and as the
// strings "inf", "-inf", "nan" otherwise (JSON has no such numbers).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "calib/search/types.h"

namespace calib::search::internal {

inline nlohmann::json DoubleToJson(double d) {
  if (std::isfinite(d)) return d;
  if (std::isnan(d)) return "nan";
  return d > 0 ? "inf" : "-inf";
}

inline double DoubleFromJson(const nlohmann::json& j) {
  if (j.is_number()) return j.get<double>();
  const std::string s = j.get<std::string>();
  if (s == "inf") return std::numeric_limits<double>::infinity();
  if (s == "-inf") return -std::numeric_limits<double>::infinity();
  if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
  throw std::invalid_argument("state: '" + s + "' is not a number");
}

inline nlohmann::json VectorToJson(const std::vector<double>& v) {
  nlohmann::json j = nlohmann::json::array();
  for (double d : v) j.push_back(DoubleToJson(d));
  return j;
}

inline std::vector<double> VectorFromJson(const nlohmann::json& j) {
  std::vector<double> v;
  v.reserve(j.size());
  for (const auto& e : j) v.push_back(DoubleFromJson(e));
  return v;
}

// An integer of a saved state, as T; `what` names it in the error. A JSON
// number that is not an integer (1e20 is read as a double) or does not fit
// T is refused: nlohmann's get<T>() would convert it with undefined
// behaviour or wrap it.
template <class T>
T IntFromJson(const nlohmann::json& j, const char* what) {
  static_assert(std::is_integral_v<T>);
  const bool fits =
      j.is_number_unsigned()
          ? j.get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<T>::max())
          : j.is_number_integer() && std::cmp_greater_equal(j.get<int64_t>(), std::numeric_limits<T>::min()) &&
                std::cmp_less_equal(j.get<int64_t>(), std::numeric_limits<T>::max());
  if (!fits) {
    throw std::invalid_argument("state: " + std::string(what) + " = " + j.dump() +
                                ": not an integer in [" + std::to_string(std::numeric_limits<T>::min()) +
                                ", " + std::to_string(std::numeric_limits<T>::max()) + "]");
  }
  return j.get<T>();
}

// An array of integers of a saved state (IntFromJson for each).
template <class T>
std::vector<T> IntVectorFromJson(const nlohmann::json& j, const char* what) {
  if (!j.is_array()) {
    throw std::invalid_argument("state: " + std::string(what) + " = " + j.dump() + ": not an array");
  }
  std::vector<T> v;
  v.reserve(j.size());
  for (const auto& e : j) v.push_back(IntFromJson<T>(e, what));
  return v;
}

// A vector of exactly `n` values (a point or a per-coordinate quantity of an
// n-dimensional search); `what` names it in the error.
inline std::vector<double> VectorFromJson(const nlohmann::json& j, size_t n, const char* what) {
  std::vector<double> v = VectorFromJson(j);
  if (v.size() != n) {
    throw std::invalid_argument("state: " + std::string(what) + " has " + std::to_string(v.size()) +
                                " values; the search has " + std::to_string(n) + " dimensions");
  }
  return v;
}

inline nlohmann::json MatrixToJson(const std::vector<std::vector<double>>& m) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& row : m) j.push_back(VectorToJson(row));
  return j;
}

inline std::vector<std::vector<double>> MatrixFromJson(const nlohmann::json& j) {
  std::vector<std::vector<double>> m;
  for (const auto& row : j) m.push_back(VectorFromJson(row));
  return m;
}

// Rows of exactly `n` values each (points of an n-dimensional search).
inline std::vector<std::vector<double>> MatrixFromJson(const nlohmann::json& j, size_t n,
                                                       const char* what) {
  std::vector<std::vector<double>> m;
  for (const auto& row : j) m.push_back(VectorFromJson(row, n, what));
  return m;
}

// Points of a saved state that must lie in the search's box (NaN does
// not); `what` names them in the error.
inline std::vector<std::vector<double>> PointsInBoxFromJson(const nlohmann::json& j,
                                                            const Bounds& bounds,
                                                            const std::string& what) {
  std::vector<std::vector<double>> points =
      MatrixFromJson(j, bounds.lower.size(), ("a point of " + what).c_str());
  for (size_t k = 0; k < points.size(); ++k) {
    for (size_t i = 0; i < points[k].size(); ++i) {
      if (!(points[k][i] >= bounds.lower[i] && points[k][i] <= bounds.upper[i])) {
        throw std::invalid_argument(fmt::format("state: point {} of {} has x[{}] = {}, outside [{}, {}]",
                                                k, what, i, points[k][i], bounds.lower[i],
                                                bounds.upper[i]));
      }
    }
  }
  return points;
}

// Maps box-normalised u in [0, 1]^n to the box, clamped so rounding never
// leaves it.
inline std::vector<double> FromUnit(const Bounds& b, const std::vector<double>& u) {
  std::vector<double> x(u.size());
  for (size_t i = 0; i < u.size(); ++i) {
    x[i] = std::clamp(b.lower[i] + u[i] * (b.upper[i] - b.lower[i]), b.lower[i], b.upper[i]);
  }
  return x;
}

// Results of one batch of candidates with consecutive ids, stored in slots
// by id so that arrival order never matters. Failed results hold +inf.
struct Batch {
  int64_t first_id = 0;
  std::vector<std::vector<double>> x;  // in the box
  std::vector<double> value;           // +inf until told, or when failed
  std::vector<uint8_t> told;
  int asked = 0;
  int told_count = 0;

  int size() const { return static_cast<int>(x.size()); }
  bool AllAsked() const { return asked == size(); }
  bool Complete() const { return told_count == size(); }

  void Reset(int64_t first, std::vector<std::vector<double>> points) {
    first_id = first;
    x = std::move(points);
    value.assign(x.size(), std::numeric_limits<double>::infinity());
    told.assign(x.size(), 0);
    asked = 0;
    told_count = 0;
  }

  std::vector<Candidate> Hand(int max_count) {
    std::vector<Candidate> out;
    while (asked < size() && static_cast<int>(out.size()) < max_count) {
      out.push_back({first_id + asked, x[asked]});
      ++asked;
    }
    return out;
  }

  // The id must be one of this batch's asked, untold ids (the checked
  // wrapper guarantees it); anything else is a bug.
  void Record(const Evaluation& e) {
    const int64_t i = e.id - first_id;
    if (i < 0 || i >= asked || told[i]) {
      throw std::logic_error("batch: result for id " + std::to_string(e.id) +
                             " does not belong to the current batch");
    }
    told[i] = 1;
    ++told_count;
    value[i] = e.failed ? std::numeric_limits<double>::infinity() : e.value;
  }

  // The asked ids not told yet. Batches follow each other without gaps and
  // a new one starts only when the last is complete, so the ids before
  // first_id have all been told.
  std::vector<int64_t> AwaitedIds() const {
    std::vector<int64_t> ids;
    for (int i = 0; i < asked; ++i) {
      if (told[i] == 0) ids.push_back(first_id + i);
    }
    return ids;
  }
  int64_t AskedTotal() const { return first_id + asked; }
  int64_t ToldTotal() const { return first_id + told_count; }

  nlohmann::json Save() const {
    nlohmann::json told_json = nlohmann::json::array();
    for (uint8_t t : told) told_json.push_back(t != 0);
    return {{"first_id", first_id}, {"x", MatrixToJson(x)}, {"value", VectorToJson(value)},
            {"told", told_json},    {"asked", asked}};
  }

  // Every point must lie in `bounds` (the search's box), asked or not.
  void Restore(const nlohmann::json& j, const Bounds& bounds) {
    first_id = IntFromJson<int64_t>(j.at("first_id"), "first_id");
    x = PointsInBoxFromJson(j.at("x"), bounds, "the batch");
    value = VectorFromJson(j.at("value"));
    told.clear();
    told_count = 0;
    for (const auto& t : j.at("told")) {
      told.push_back(t.get<bool>() ? 1 : 0);
      told_count += told.back();
    }
    asked = IntFromJson<int>(j.at("asked"), "asked");
    if (value.size() != x.size() || told.size() != x.size() || asked < 0 || asked > size()) {
      throw std::invalid_argument("state: batch sizes disagree");
    }
  }
};

// Indices 0..n-1 sorted by value, ties by index (failed = +inf last).
inline std::vector<int> RankOrder(const std::vector<double>& value) {
  std::vector<int> order(value.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return value[a] < value[b]; });
  return order;
}

}  // namespace calib::search::internal
