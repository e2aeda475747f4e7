// A job's convergence plot (convergence_plot.h): the points and the best so
// far it plots, failures counted, and the SVG gnuplot makes of it.

#include "calib/results/convergence_plot.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace calib {
namespace {

EvaluationRecord Evaluation(int64_t id, bool ok, double score) {
  EvaluationRecord e;
  e.id = id;
  e.ok = ok;
  e.score = ok ? score : std::numeric_limits<double>::quiet_NaN();
  return e;
}

TEST(ConvergencePlot, PlotsEachFinishedScoreAndTheBestSoFarAndCountsFailures) {
  const std::vector<EvaluationRecord> evaluations{Evaluation(0, true, 50.0), Evaluation(1, false, 0.0),
                                                  Evaluation(2, true, 70.0), Evaluation(3, true, 20.0)};
  const std::string script = ConvergencePlotScript(evaluations, "job");
  // Points: the three finished evaluations at their evaluation counts.
  EXPECT_NE(script.find("$points << EOD\n1 50\n3 70\n4 20\nEOD\n"), std::string::npos) << script;
  // Best so far after each evaluation, the failed one included.
  EXPECT_NE(script.find("$best << EOD\n1 50\n2 50\n3 50\n4 20\nEOD\n"), std::string::npos) << script;
  EXPECT_NE(script.find("job: 4 evaluations, 1 failed"), std::string::npos) << script;
  EXPECT_EQ(ConvergencePlotScript({Evaluation(0, false, 0.0)}, "job"), "") << "nothing finished: no plot";
}

TEST(ConvergencePlot, WritesAnSvgOrNamesWhyNot) {
  const std::filesystem::path dir = testing::ScratchDir("convergence_plot");
  try {
    WriteConvergencePlot(dir / "none.svg", {Evaluation(0, false, 0.0)}, "failing");
    ADD_FAILURE() << "a plot of nothing was written";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no evaluation of 'failing' finished"), std::string::npos) << e.what();
  }
  std::string message;
  if (!GnuplotAvailable("gnuplot", &message)) GTEST_SKIP() << message;
  WriteConvergencePlot(dir / "c.svg", {Evaluation(0, true, 3.0), Evaluation(1, true, 1.0)}, "job");
  std::ifstream in(dir / "c.svg");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("<svg"), std::string::npos);
  EXPECT_NE(text.str().find("best so far"), std::string::npos);
}

}  // namespace
}  // namespace calib
