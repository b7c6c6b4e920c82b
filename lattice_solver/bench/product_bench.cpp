// Cost of the stiffness product K x, the kernel of every cg iteration (issue 7, docs/performance.md).
//
//   product_bench SCENE.yaml [--set KEY=VALUE …] [--products 100] [--rounds 5] [--threads 2] [--single]
//
// Generates the scene's specimen, builds its model with the scene's operator (matrix-free rod pass or
// assembled blocks) and times rounds of `products` products y = K x on a fixed random x; prints each
// round, the median time per product and per rod, and ‖y‖ (the same for every build of one kernel).
// --single times the single-precision product of mixed-precision cg instead (Model::applySingle, in
// the padded node space; matrix-free only).
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "lattice/model.hpp"
#include "lattice/scene.hpp"

int main(int argc, char** argv) {
  CLI::App app{"Times the lattice stiffness product K x on a scene's specimen"};
  std::string scenePath;
  std::vector<std::string> sets;
  int products = 100, rounds = 5, threads = 2;
  bool single = false;
  app.add_option("scene", scenePath, "lattice scene (YAML)")->required()->check(CLI::ExistingFile);
  app.add_option("--set", sets, "override a scene key, KEY=VALUE");
  app.add_option("--products", products, "products per round")->check(CLI::PositiveNumber);
  app.add_option("--rounds", rounds, "rounds (the median is reported)")->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "OpenMP threads")->check(CLI::PositiveNumber);
  app.add_flag("--single", single, "time the single-precision product (matrix-free operator)");
  CLI11_PARSE(app, argc, argv);
  try {
    omp_set_num_threads(threads);
    const lattice::Scene scene = lattice::loadScene(common::Config::load(scenePath, sets));
    const lattice::Model model = lattice::buildModel(scene);
    const auto n = static_cast<Eigen::Index>(model.freeDofs());
    Eigen::VectorXd x(n), y(n);
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(-1e-6, 1e-6);
    for (Eigen::Index i = 0; i < n; ++i) x[i] = u(rng);
    Eigen::VectorXf x6, y6;
    model.toPadded(x, 1.0, x6);
    auto product = [&] {
      if (single) model.applySingle(x6, y6);
      else model.apply(x, y);
    };
    product();  // warm-up: scratch vectors sized, pages touched
    fmt::print("{} rods, {} free dofs, {} threads, {} {}-precision products per round\n", model.rods(), n, threads, products,
               single ? "single" : "double");
    std::vector<double> perProduct;
    for (int r = 0; r < rounds; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      for (int k = 0; k < products; ++k) product();
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / products;
      perProduct.push_back(s);
      fmt::print("round {}: {:.3f} ms per product\n", r + 1, 1e3 * s);
    }
    std::sort(perProduct.begin(), perProduct.end());
    const double med = perProduct[perProduct.size() / 2];
    fmt::print("median {:.3f} ms per product, {:.2f} ns per rod, |Kx| = {:.17g}\n", 1e3 * med,
               1e9 * med / static_cast<double>(model.rods()), single ? static_cast<double>(y6.norm()) : y.norm());
  } catch (const common::ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 1;
  }
  return 0;
}
