// fem_solver: finite elements (membranes, trusses, tetrahedra), static and explicit. Run with:
//   fem_solver configs/fem/net_deadload.yaml [--out DIR] [--set KEY=VALUE …] [--check]
// In a coupled run (started by cosim): fem_solver SCENE.yaml --couple ENDPOINT --name NAME
#include <CLI/CLI.hpp>

#include "common/app.hpp"
#include "fem/scene.hpp"
#include "participant_main.hpp"

int main(int argc, char** argv) {
  std::string endpoint, name;
  return common::runApp(
      argc, argv, {"fem_solver", "Finite element solver (membranes, trusses, tets; static, explicit)", "0.1.0"},
      [&](CLI::App& app) {
        app.add_option("--couple", endpoint, "join the coupled run at this endpoint (set by cosim)");
        app.add_option("--name", name, "participant name in the coupled run");
      },
      [&](common::RunContext& ctx) {
        fem::Scene scene = fem::loadScene(ctx.scene);
        if (ctx.options.check) return;
        if (!endpoint.empty()) fem::runParticipant(scene, endpoint, name.empty() ? "fem" : name, ctx.options.outDir, ctx.summary,
                                                 common::restartFile(ctx.options));
        else fem::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet,
                           common::restartFile(ctx.options, ctx.options.outDir / "checkpoint" / "fem.h5"));
      });
}
