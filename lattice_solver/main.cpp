// lattice_solver: fracture of concrete with the Lattice Geometrical Model (Kozicki & Tejchman). Run with:
//   lattice_solver configs/lattice/tension_5cm.yaml [--out DIR] [--set KEY=VALUE …] [--check]
#include "common/app.hpp"
#include "lattice/scene.hpp"

int main(int argc, char** argv) {
  return common::runApp(
      argc, argv, {"lattice_solver", "Lattice fracture solver (LGM rods, three-phase concrete, uniaxial tests)", "0.1.0"},
      nullptr, [&](common::RunContext& ctx) {
        lattice::Scene scene = lattice::loadScene(ctx.scene);
        if (ctx.options.check) return;
        lattice::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet);
      });
}
