#pragma once
// Enum values as text: one table per enum (EnumNames, every value with its
// name), read both ways by EnumToString and EnumFromString, so that the two
// directions cannot drift apart and an unknown text is reported the same way
// for every enum: "<what> '<text>' is unknown; expected a, b or c".
// Each enum keeps its own ToString / ...FromString functions (the public
// names callers use); they are one line each over their table:
//
//   constexpr auto kScaleNames = std::to_array<EnumName<ParameterScale>>(
//       {{ParameterScale::kLinear, "linear"}, {ParameterScale::kLog, "log"}});
//   std::string ToString(ParameterScale s) { return EnumToString(kScaleNames, s); }
//   ParameterScale ParameterScaleFromString(const std::string& name) {
//     return EnumFromString(kScaleNames, "scale", name);
//   }

#include <array>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace calib {

/// One enum value and its text.
template <typename E>
struct EnumName {
  E value;
  std::string_view name;
};

/// Every value of an enum with its text, in the order messages list them.
template <typename E, std::size_t N>
using EnumNames = std::array<EnumName<E>, N>;

/// The names in the table as a message lists them: "a", "a or b", "a, b or c".
template <typename E, std::size_t N>
std::string EnumNameList(const EnumNames<E, N>& names) {
  std::string list;
  for (std::size_t i = 0; i < N; ++i) {
    if (i > 0) list += i + 1 == N ? " or " : ", ";
    list += names[i].name;
  }
  return list;
}

/// The text of `value`; "?" for a value the table lacks (every table lists
/// all of its enum's values, so only a value cast from an unchecked integer).
template <typename E, std::size_t N>
std::string EnumToString(const EnumNames<E, N>& names, E value) {
  for (const EnumName<E>& n : names) {
    if (n.value == value) return std::string(n.name);
  }
  return "?";
}

/// The value named `text`. Throws std::invalid_argument naming what is read
/// (`what`, e.g. "integrator"), the text and the valid names:
/// "integrator 'rk4' is unknown; expected first_order, verlet or implicit_first_order".
template <typename E, std::size_t N>
E EnumFromString(const EnumNames<E, N>& names, std::string_view what, std::string_view text) {
  for (const EnumName<E>& n : names) {
    if (n.name == text) return n.value;
  }
  throw std::invalid_argument(std::string(what) + " '" + std::string(text) + "' is unknown; expected " +
                              EnumNameList(names));
}

}  // namespace calib
