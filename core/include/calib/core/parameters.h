#pragma once
// Named model parameters. The set is open: each model term declares the
// parameters it needs as ParameterSpecs, and a parameter file or a candidate
// is a map from those names to values.

#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace calib {

/// Thrown for a bad parameter file or value; what() names the file and key.
class ParameterError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// How a searched parameter's box maps to the optimiser's unit interval:
/// evenly (linear) or evenly in its logarithm (log; the box then lies in
/// (0, inf)).
enum class ParameterScale { kLinear, kLog };
std::string ToString(ParameterScale scale);  ///< "linear" / "log"
/// Throws std::invalid_argument naming the value.
ParameterScale ParameterScaleFromString(const std::string& name);

/// What the recordings of a calibration show that sizes its search boxes
/// (SearchBox below). With several training recordings they combine as the
/// fields say: the largest force and drag, the longest duration, and the
/// frame rate and pixel scale of the first (the boxes reach far enough for
/// the others' to fit).
/// With inertia on a freely swinging object, the stiffness boxes reach
/// this factor either side of SearchScales::swing_stiffness: 10^1.5.
inline constexpr double kSwingStiffnessReach = 31.6227766016838;

struct SearchScales {
  double peak_force = 0.0;  ///< largest |force| of the training tracks; 0: no sensor
  double fps = 30.0;        ///< frame rate of the first training recording
  double duration_s = 1.0;  ///< longest training recording
  double mm_per_px = 0.0;   ///< of the first training recording; 0: unknown
  /// The model's own force scale: the first-order drag of the whole mesh
  /// moving at the fastest obstacle's speed, nodes x mass x speed (largest
  /// over the training recordings). The model's forces are not in the
  /// sensor's unit (only stiffness / mass ratios are calibrated), so forces
  /// that compete with the model's motion are sized on this. 0: no obstacle
  /// moves.
  double drag_force = 0.0;
  /// The stiffness boxes reach this many times higher: 100 with the
  /// implicit step, which is stable there (the quasi-static regime of a
  /// pushed sponge); 1 with an explicit step.
  double stiffness_reach = 1.0;
  /// With inertia, for an object the video shows swinging freely: the
  /// common stiffness (k_D = k_A = k_phi, force*px) at which the model's
  /// slowest free vibration, nodes of the calibration mass, has the period
  /// the video shows (free_modes.h). The stiffness boxes are then centred
  /// on it: the second-order model's stiffness is set by the swing's
  /// period, not by the first-order model's relaxation. 0: not known, or
  /// the model has no inertia.
  double swing_stiffness = 0.0;
  /// The swing's period it was set from, s (0 with it).
  double swing_period_s = 0.0;
  /// For a clamped object, the direction from the clamps' centre to the
  /// object's mean centroid over the video, degrees in the image (0: +x,
  /// 90: +y, down): the object hangs that way, so gravity points within 90
  /// degrees of it. NaN: not known.
  double hanging_angle_deg = std::numeric_limits<double>::quiet_NaN();
  /// The previous fit's values, when a calibration continues one (an
  /// effect's box may scale with a base value, e.g. k_D); empty otherwise.
  std::map<std::string, double> reference;

  /// `value` when it is finite and > 0, else `fallback`.
  static double Positive(double value, double fallback);
  /// Positive(reference[name], fallback); `fallback` without that entry.
  double Reference(const std::string& name, double fallback) const;
};

/// Where a calibration searches one parameter by default: within [lower,
/// upper] on `scale`, or held at `fixed`.
struct SearchBox {
  double lower = 0.0;
  double upper = 0.0;
  ParameterScale scale = ParameterScale::kLinear;
  std::optional<double> fixed;

  static SearchBox Linear(double lower, double upper) { return {lower, upper, ParameterScale::kLinear, {}}; }
  static SearchBox Log(double lower, double upper) { return {lower, upper, ParameterScale::kLog, {}}; }
  static SearchBox Fixed(double value) { return {value, value, ParameterScale::kLinear, value}; }
};

/// What a parameter means, which values it may take, and how a calibration
/// searches it.
struct ParameterSpec {
  std::string name;         ///< key in parameter files, e.g. "k_D"
  std::string unit;         ///< e.g. "force*px"
  std::string description;
  double lower = 0.0;       ///< smallest allowed value
  double upper = 0.0;       ///< largest allowed value (may be +inf)
  bool lower_open = false;  ///< lower bound excluded (e.g. mass > 0)
  /// The box a calibration searches by default, sized on what the
  /// recordings show (calib loop's calibrations). Every base and effect
  /// parameter has one.
  std::function<SearchBox(const SearchScales&)> search_box;
  /// An effect's parameter: its value that leaves the model (nearly) as it
  /// was without the effect, given the box searched (the warm start of a
  /// new effect). Null: the box's lower end.
  std::function<double(const SearchBox&)> neutral;

  /// search_box(scales); throws std::logic_error naming the parameter when
  /// it has none.
  SearchBox SearchBoxFor(const SearchScales& scales) const;
  /// The neutral value in `box` (its fixed value when fixed).
  double NeutralIn(const SearchBox& box) const;
};

/// Parameter values by name (ordered, so iteration is deterministic).
using ParameterValues = std::map<std::string, double>;

/// The node mass m a calibration holds fixed (its search box): with the
/// first-order integrator only stiffness / mass ratios matter.
inline constexpr double kCalibrationMass = 0.2;

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

/// LoadParameterFile on the file's text in memory (tests, fuzz/); `source`
/// names it in messages.
ParameterValues ParseParameterFile(std::string_view text, const std::string& source,
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
