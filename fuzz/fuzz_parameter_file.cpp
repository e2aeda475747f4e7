// Fuzz target: parameter files (ParseParameterFile, the reader behind
// LoadParameterFile: a JSON object of name -> number) against the base
// model's parameters. Expected: values that pass ValidateParameters, or
// ParameterError.

#include "calib/core/parameters.h"
#include "fuzz_support.h"

#include <cstdio>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace calib;
  const std::vector<ParameterSpec>& specs = BaseModelParameterSpecs();
  ParameterValues values;
  try {
    values = ParseParameterFile(fuzz::Text(data, size), "fuzz.json", specs);
  } catch (const ParameterError&) {
    return 0;
  } catch (...) {
    fuzz::Unexpected("fuzz_parameter_file");
  }
  try {
    ValidateParameters(values, specs, "fuzz.json (accepted)");
    (void)ModelParameters::FromValues(values);
  } catch (...) {
    fuzz::Unexpected("fuzz_parameter_file (accepted values)");
  }
  return 0;
}
