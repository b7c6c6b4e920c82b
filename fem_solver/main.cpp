// fem_solver: finite elements (membranes, trusses), static and explicit, standalone. Run with:
//   fem_solver configs/fem/net_deadload.yaml [--out DIR] [--set KEY=VALUE …] [--check]
#include "common/app.hpp"
#include "fem/scene.hpp"

int main(int argc, char** argv) {
  return common::runApp(argc, argv, {"fem_solver", "Finite element solver (membranes, trusses; static, explicit)", "0.1.0"},
                        nullptr, [](common::RunContext& ctx) {
                          fem::Scene scene = fem::loadScene(ctx.scene);
                          if (ctx.options.check) return;
                          fem::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet);
                        });
}
