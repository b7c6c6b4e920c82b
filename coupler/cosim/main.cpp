// cosim: runs a coupled scene. Run with:
//   cosim run configs/verification/split_bar_static.yaml [--out DIR] [--set KEY=VALUE …]
//   cosim run configs/rockfall/c5.yaml --set dem:dt=2e-5      (a participant's own scene key)
//   cosim check configs/verification/split_bar_static.yaml
//   cosim study configs/studies/hertz_dt.yaml [--out DIR] [-j N] [--quiet]   (error against run time)
//   cosim keys PREFIX          (a CURVE key pair for a coupler reachable from other hosts)
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/app.hpp"
#include "coupler.hpp"
#include "router.hpp"

namespace {
const char* kOverview =
    "cosim: runs a coupled scene of independent solvers (docs/guide.md)\n"
    "\n"
    "usage:\n"
    "  cosim run SCENE [--out DIR] [--set KEY=VALUE ...] [--set NAME:KEY=VALUE ...] [--restart] [--quiet]\n"
    "                                  run a coupled scene (NAME:KEY sets a key of participant NAME's scene)\n"
    "  cosim check SCENE [--set ...]   read and check a coupled scene; run nothing\n"
    "  cosim study STUDY [--out DIR] [-j N] [--quiet]\n"
    "                                  error against run time over the parameter ladders of a study file\n"
    "  cosim keys PREFIX               a CURVE key pair for a coupler other hosts can reach\n"
    "\n"
    "Each subcommand has its own --help.\n";
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::fputs(kOverview, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  // `cosim study`: the study runner (tools/study.py: ladders, cache, table, plot, order fit) with this
  // build's executables.
  if (argc > 1 && std::string(argv[1]) == "study") {
    const std::string bin = std::filesystem::canonical("/proc/self/exe").parent_path().string();
    const std::string script = std::string(COSIM_SOURCE_DIR) + "/tools/study.py";
    std::vector<std::string> words{COSIM_PYTHON, script, "--bin", bin};
    for (int i = 2; i < argc; ++i) words.emplace_back(argv[i]);
    std::vector<char*> exec;
    for (auto& w : words) exec.push_back(w.data());
    exec.push_back(nullptr);
    execv(exec[0], exec.data());
    std::fprintf(stderr, "[cosim] error: cannot start %s %s: %s\n", COSIM_PYTHON, script.c_str(), std::strerror(errno));
    return 1;
  }
  // `cosim keys PREFIX`: a CURVE key pair for a coupler reachable from other hosts (coupler/README.md).
  if (argc > 1 && std::string(argv[1]) == "keys") {
    if (argc == 3 && (std::string(argv[2]) == "--help" || std::string(argv[2]) == "-h")) {
      std::printf("usage: cosim keys PREFIX\n  writes a CURVE key pair: PREFIX.secret (mode 600: the coupler's "
                  "coupling.curve.secret_key_file, or a participant's COSIM_CURVE_SECRET_KEY_FILE) and PREFIX.public "
                  "(COSIM_CURVE_SERVER_KEY, or an entry of coupling.curve.allowed_keys)\n");
      return 0;
    }
    if (argc != 3) {
      std::fprintf(stderr, "usage: cosim keys PREFIX   (writes PREFIX.secret, mode 600, and PREFIX.public)\n");
      return 2;
    }
    try {
      const auto [pub, sec] = cosim::newCurveKeyPair();
      const std::string prefix = argv[2];
      cosim::writeSecretFile(prefix + ".secret", sec + "\n");
      std::ofstream(prefix + ".public") << pub << "\n";
      std::printf("%s.secret: the coupler's secret key (coupling.curve.secret_key_file; keep it private)\n"
                  "%s.public: %s (participants: COSIM_CURVE_SERVER_KEY=%s; or, as a participant's own pair, "
                  "coupling.curve.allowed_keys)\n",
                  prefix.c_str(), prefix.c_str(), pub.c_str(), pub.c_str());
      return 0;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "[cosim] error: %s\n", e.what());
      return 2;
    }
  }
  // `cosim run FILE` and `cosim check FILE` are the user-facing verbs; the common command line
  // does the rest.
  std::vector<const char*> args(argv, argv + argc);
  if (args.size() > 1 && std::string(args[1]) == "run") args.erase(args.begin() + 1);
  else if (args.size() > 1 && std::string(args[1]) == "check") {
    args.erase(args.begin() + 1);
    args.push_back("--check");
  }
  // `--set NAME:KEY=VALUE` belongs to participant NAME's scene: taken out here, before the coupled scene
  // reads its own overrides, and appended to that participant's command once the scene is loaded.
  std::vector<std::string> participantSets;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string a = args[i];
    if (a != "--set" && a != "-s") continue;
    std::size_t j = i + 1;
    while (j < args.size() && args[j][0] != '-') {
      std::vector<std::string> one{args[j]};
      if (cosim::takeParticipantOverrides(one).empty()) {
        ++j;
        continue;
      }
      participantSets.push_back(args[j]);
      args.erase(args.begin() + static_cast<std::ptrdiff_t>(j));
    }
    if (j == i + 1) args.erase(args.begin() + static_cast<std::ptrdiff_t>(i--));  // a --set left empty
  }
  const auto byParticipant = cosim::takeParticipantOverrides(participantSets);
  const std::filesystem::path binDir = std::filesystem::canonical("/proc/self/exe").parent_path();
  return common::runApp(static_cast<int>(args.size()), args.data(),
                        {"cosim", "Coupler: runs a coupled scene of independent solvers", "0.1.0"}, nullptr,
                        [&](common::RunContext& ctx) {
                          cosim::CoupledScene scene = cosim::loadCoupledScene(ctx.scene);
                          ctx.scene.checkUnknownKeys();
                          cosim::applyParticipantOverrides(scene, byParticipant);
                          if (ctx.options.check) return;
                          if (ctx.options.restart && !ctx.options.restart->empty())
                            throw common::ConfigError(fmt::format(
                                "--restart {}: cosim continues from the last checkpoint in --out; give --restart alone",
                                ctx.options.restart->string()));
                          cosim::runCoupled(scene, ctx.options.outDir, binDir, ctx.summary, !ctx.options.quiet,
                                            ctx.options.restart.has_value());
                        });
}
