// Genetic algorithm (real-coded), after the paper's: a population evolved
// for a number of generations by tournament selection, crossover, gaussian
// mutation and elitism.
//
// Generation 0 is uniform in the box. Each later generation keeps the
// `elitism` best individuals (not re-evaluated) and breeds the rest: two
// parents by tournament (each the best of `tournament_size` draws with
// replacement; ties to the lower index), crossover with probability
// `crossover_rate` (otherwise copies), then each gene mutated with
// probability `mutation_rate` by adding N(0, (mutation_sigma * width)^2);
// children are clipped to the box. Failed evaluations rank last. One batch
// = one generation's new individuals (population - elitism after the
// first). Budget: population + (generations - 1) * (population - elitism).
//
// Crossover (per gene, in the box's coordinates):
//   "blend": BLX-alpha (Eshelman & Schaffer 1993), child uniform in
//            [min - alpha d, max + alpha d], d = |p1 - p2|.
//   "sbx":   simulated binary crossover (Deb & Agrawal 1995), index eta.
//
// Settings (JSON object):
//   population       integer >= 2                      default 20
//   generations      integer >= 1                      default 10
//   tournament_size  integer in [1, population]        default 2
//   crossover        "blend" or "sbx"                  default "blend"
//   crossover_rate   number in [0, 1]                  default 0.9
//   blend_alpha      number >= 0                       default 0.5
//   sbx_eta          number >= 0                       default 15
//   mutation_rate    number in [0, 1], per gene        default 1/n
//   mutation_sigma   number > 0, fraction of width     default 0.1
//   elitism          integer in [0, population - 1]    default 1
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct GeneticOptions {
  int population = 20;
  int generations = 10;
  int tournament_size = 2;
  std::string crossover = "blend";
  double crossover_rate = 0.9;
  double blend_alpha = 0.5;
  double sbx_eta = 15.0;
  double mutation_rate = -1.0;  // < 0: 1/n
  double mutation_sigma = 0.1;
  int elitism = 1;

  static GeneticOptions FromJson(const nlohmann::json& settings, int dimension);
};

std::unique_ptr<Optimizer> MakeGenetic(const GeneticOptions& options, const Bounds& bounds,
                                       uint64_t seed);

}  // namespace calib::search
