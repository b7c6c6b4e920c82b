// cosim: runs a coupled scene. Run with:
//   cosim run configs/verification/split_bar_static.yaml [--out DIR] [--set KEY=VALUE …]
//   cosim check configs/verification/split_bar_static.yaml
#include <filesystem>
#include <string>
#include <vector>

#include "common/app.hpp"
#include "coupler.hpp"

int main(int argc, char** argv) {
  // `cosim run FILE` and `cosim check FILE` are the user-facing verbs; the common command line
  // (DESIGN.md §10) does the rest.
  std::vector<const char*> args(argv, argv + argc);
  if (args.size() > 1 && std::string(args[1]) == "run") args.erase(args.begin() + 1);
  else if (args.size() > 1 && std::string(args[1]) == "check") {
    args.erase(args.begin() + 1);
    args.push_back("--check");
  }
  const std::filesystem::path binDir = std::filesystem::canonical("/proc/self/exe").parent_path();
  return common::runApp(static_cast<int>(args.size()), args.data(),
                        {"cosim", "Coupler: runs a coupled scene of independent solvers", "0.1.0"}, nullptr,
                        [&](common::RunContext& ctx) {
                          const cosim::CoupledScene scene = cosim::loadCoupledScene(ctx.scene);
                          ctx.scene.checkUnknownKeys();
                          if (ctx.options.check) return;
                          cosim::runCoupled(scene, ctx.options.outDir, binDir, ctx.summary, !ctx.options.quiet);
                        });
}
