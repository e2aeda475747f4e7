#pragma once
// Named model parameters. The set is open: each model term declares the
// parameters it needs as ParameterSpecs, and a parameter file or a candidate
// is a map from those names to values.

#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {

/// Thrown for a bad parameter file or value; what() names the file and key.
class ParameterError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a parameter means and which values it may take.
struct ParameterSpec {
  std::string name;         ///< key in parameter files, e.g. "k_D"
  std::string unit;         ///< e.g. "force*px"
  std::string description;
  double lower = 0.0;       ///< smallest allowed value
  double upper = 0.0;       ///< largest allowed value (may be +inf)
  bool lower_open = false;  ///< lower bound excluded (e.g. mass > 0)
};

/// Parameter values by name (ordered, so iteration is deterministic).
using ParameterValues = std::map<std::string, double>;

/// The base model's parameters: k_D, k_d, k_A, k_phi, mass, tau.
const std::vector<ParameterSpec>& BaseModelParameterSpecs();

/// Checks that `values` holds exactly the names in `specs`, each finite and
/// within its bounds. Throws ParameterError naming `source` (a file name or
/// "parameters"), the key and the rule violated.
void ValidateParameters(const ParameterValues& values, const std::vector<ParameterSpec>& specs,
                        const std::string& source);

/// Reads a parameter file: a JSON object of name -> number. Throws
/// ParameterError naming the file and key for unreadable files, invalid JSON,
/// non-numeric values, and names missing from or unknown to `specs`.
ParameterValues LoadParameterFile(const std::filesystem::path& path,
                                  const std::vector<ParameterSpec>& specs);

/// Writes a parameter file that LoadParameterFile reads back exactly.
void SaveParameterFile(const std::filesystem::path& path, const ParameterValues& values);

/// The base model's parameters as a plain struct for the hot loop.
struct ModelParameters {
  double k_distance = 0.0;   ///< k_D, distance spring stiffness, force*px
  double k_damping = 0.0;    ///< k_d, Teschner edge damping, force*px*s
  double k_area = 0.0;       ///< k_A, area spring stiffness, force*px
  double k_angle = 0.0;      ///< k_phi, angle spring stiffness, force*px/rad^2
  double mass = 1.0;         ///< m, mass of each node, force*s^2/px
  double translation = 0.0;  ///< tau in [0, 1], share of the push spread over all nodes

  /// From validated values (ValidateParameters with BaseModelParameterSpecs).
  static ModelParameters FromValues(const ParameterValues& values);
  ParameterValues ToValues() const;
};

}  // namespace calib
