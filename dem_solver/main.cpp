// dem_solver: discrete elements, standalone. Run with:
//   dem_solver configs/dem/hertz_bounce.yaml [--out DIR] [--set KEY=VALUE …] [--check]
// In a coupled run (started by cosim): dem_solver SCENE.yaml --couple ENDPOINT --name NAME
// On several ranks: mpirun -np P dem_solver SCENE.yaml [--couple …] (dem/ranked_run.hpp)
#include <malloc.h>

#include <CLI/CLI.hpp>

#include "common/app.hpp"
#include "common/errors.hpp"
#include "dem/ranked_run.hpp"
#include "dem/scene.hpp"
#include "dem/triaxial.hpp"
#include "participant_main.hpp"

int main(int argc, char** argv) {
  // One malloc arena for all threads. glibc gives each thread that allocates an arena of its own; the
  // pair search's per-thread lists grow there, and what they free stays mapped per arena: at 10⁵ spheres,
  // 3,000 steps, two threads held 18 MB more than one. The step allocates nothing in its hot loops, so
  // the shared arena's lock is not contended (docs/performance.md, DEM memory).
  mallopt(M_ARENA_MAX, 1);
  const dem::Ranks ranks = dem::startRanks(&argc, &argv);
  std::string endpoint, name;
  common::AppInfo info{"dem_solver", "Discrete element solver (spheres, clusters, Hertz–Mindlin, walls)", "0.1.0"};
  if (ranks.rank > 0) info.ownFolder = "rank_" + std::to_string(ranks.rank);
  const int code = common::runApp(
      argc, argv, info,
      [&](CLI::App& app) {
        app.add_option("--couple", endpoint, "join the coupled run at this endpoint (set by cosim)");
        app.add_option("--name", name, "participant name in the coupled run");
      },
      [&](common::RunContext& ctx) {
        if (dem::isTriaxialScene(ctx.scene)) {
          if (ranks.size > 1) throw common::ConfigError("a triaxial test (a scene with triaxial:) runs on one rank.");
          common::refuseRestart(ctx.options, "a triaxial test");
          if (!endpoint.empty())
            throw common::ConfigError("a triaxial test (a scene with triaxial:) runs standalone; leave out --couple.");
          dem::TriaxialScene test = dem::loadTriaxialScene(ctx.scene);
          if (!ctx.options.check) dem::runTriaxial(test, ctx.options.outDir, ctx.summary, !ctx.options.quiet);
          return;
        }
        // On several ranks each initializes its share (dem/ranked_run.hpp).
        dem::Scene scene = dem::loadScene(ctx.scene, ranks.size == 1 || ctx.options.check);
        if (ctx.options.check) return;
        if (ranks.size > 1 && !endpoint.empty()) {
          if (ctx.options.restart)
            throw common::ConfigError("--restart: a coupled participant on several ranks writes no checkpoints to "
                                      "continue from; start the coupled run again, or run its DEM on one rank");
          dem::runParticipantOnRanks(scene, ranks, endpoint, name.empty() ? "dem" : name, ctx.options.outDir,
                                     ctx.summary, ctx.options.threads);
          return;
        }
        if (ranks.size > 1) {
          dem::runSceneOnRanks(scene, ranks, ctx.options.outDir, ctx.summary, !ctx.options.quiet, ctx.options.threads,
                               common::restartFile(ctx.options, ctx.options.outDir / "checkpoint" / "dem.h5"));
          return;
        }
        if (!endpoint.empty())
          dem::runParticipant(scene, endpoint, name.empty() ? "dem" : name, ctx.options.outDir, ctx.summary,
                              common::restartFile(ctx.options));
        else
          dem::runScene(scene, ctx.options.outDir, ctx.summary, !ctx.options.quiet,
                        common::restartFile(ctx.options, ctx.options.outDir / "checkpoint" / "dem.h5"));
      });
  dem::stopRanks(code);
  return code;
}
