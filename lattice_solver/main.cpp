// lattice_solver: fracture of concrete with the Lattice Geometrical Model (Kozicki & Tejchman). Run with:
//   lattice_solver configs/lattice/tension_5cm.yaml [--out DIR] [--set KEY=VALUE …] [--check]
// In a coupled run (started by cosim): lattice_solver SCENE.yaml --couple ENDPOINT --name NAME
#include <CLI/CLI.hpp>

#include "common/app.hpp"
#include "lattice/scene.hpp"
#include "participant_main.hpp"

int main(int argc, char** argv) {
  std::string endpoint, name;
  return common::runApp(
      argc, argv, {"lattice_solver", "Lattice fracture solver (LGM rods, three-phase concrete, uniaxial tests, coupled)", "0.1.0"},
      [&](CLI::App& app) {
        app.add_option("--couple", endpoint, "join the coupled run at this endpoint (set by cosim)");
        app.add_option("--name", name, "participant name in the coupled run");
      },
      [&](common::RunContext& ctx) {
        lattice::Scene scene = lattice::loadScene(ctx.scene);
        if (ctx.options.check) return;
        if (!endpoint.empty())
          lattice::runParticipant(scene, endpoint, name.empty() ? "lattice" : name, ctx.options.outDir, ctx.summary,
                                  common::restartFile(ctx.options));
        else
          lattice::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet,
                            common::restartFile(ctx.options, ctx.options.outDir / "checkpoint" / "lattice.h5", "output.checkpoint_every"));
      });
}
