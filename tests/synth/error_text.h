#pragma once
// Bad-input tests of the synth file formats (scenarios, scene families): the
// message a parse throws, and that it names what it must.

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace calib::testing {

/// The what() of the `Error` that `parse` throws; "" when it throws none.
template <typename Error, typename Parse>
std::string ErrorOf(Parse&& parse) {
  try {
    parse();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// Expects a message (non-empty: the input was refused) containing every
/// one of `parts`; `input` is shown when the input was accepted.
inline void ExpectMessageNames(const std::string& error, const std::string& input,
                               const std::vector<std::string>& parts) {
  ASSERT_FALSE(error.empty()) << "accepted:\n" << input;
  for (const auto& part : parts) EXPECT_NE(error.find(part), std::string::npos) << error;
}

}  // namespace calib::testing
