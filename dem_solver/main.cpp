// dem_solver: discrete elements, standalone. Run with:
//   dem_solver configs/dem/hertz_bounce.yaml [--out DIR] [--set KEY=VALUE …] [--check]
#include "common/app.hpp"
#include "common/log.hpp"
#include "dem/scene.hpp"

int main(int argc, char** argv) {
  return common::runApp(argc, argv, {"dem_solver", "Discrete element solver (spheres, Hertz–Mindlin, walls)", "0.1.0"},
                        nullptr, [](common::RunContext& ctx) {
                          dem::Scene scene = dem::loadScene(ctx.scene);
                          if (ctx.options.check) return;
                          dem::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet);
                        });
}
