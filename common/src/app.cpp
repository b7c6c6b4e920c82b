#include "common/app.hpp"

#include <omp.h>

#include <sys/resource.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "common/log.hpp"

namespace common {

void refuseRestart(const RunOptions& options, const std::string& what) {
  if (options.restart)
    throw ConfigError(fmt::format("--restart {}: {} cannot continue from a checkpoint yet; a coupled run can "
                                  "(cosim run SCENE --out DIR --restart)",
                                  options.restart->string(), what));
}

std::filesystem::path restartFile(const RunOptions& options, const std::filesystem::path& standalone, const std::string& key) {
  if (!options.restart) return {};
  if (!options.restart->empty()) return *options.restart;
  if (standalone.empty()) throw ConfigError("--restart: name the checkpoint file to continue from (--restart FILE)");
  if (!std::filesystem::exists(standalone))
    throw ConfigError(fmt::format("--restart: {} holds no checkpoint ({} is missing; {} writes one)", options.outDir.string(),
                                  standalone.string(), key));
  return standalone;
}

int runApp(int argc, const char* const* argv, const AppInfo& info, const std::function<void(CLI::App&)>& addOptions,
           const std::function<void(RunContext&)>& run) {
  CLI::App app(info.description, info.name);
  app.set_version_flag("--version", info.version);
  RunContext ctx;
  RunOptions& o = ctx.options;
  app.add_option("scene", o.scenePath, "scene file (YAML)")->required()->check(CLI::ExistingFile);
  app.add_option("--out,-o", o.outDir, "results folder (default: results/<scene name>)");
  app.add_option("--set,-s", o.overrides, "override a scene key: KEY.PATH=VALUE (repeatable)")->take_all();
  app.add_option("--threads,-j", o.threads, "OpenMP threads (default: all cores)")->check(CLI::NonNegativeNumber);
  app.add_flag("--quiet,-q", o.quiet, "only warnings and errors on the console");
  app.add_flag("--check", o.check, "validate the scene and exit");
  std::filesystem::path restart;
  CLI::Option* restartOption =
      app.add_option("--restart", restart, "continue from a checkpoint (FILE; cosim: the last one in --out), appending "
                                           "to --out's results")
          ->expected(0, 1);
  if (addOptions) addOptions(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : static_cast<int>(ExitCode::kBadInput);
  }
  if (restartOption->count() > 0) o.restart = restart;

  const auto start = std::chrono::steady_clock::now();
  const std::string stem = o.scenePath.stem().string();
  if (o.outDir.empty()) o.outDir = std::filesystem::path("results") / stem;
  ctx.summary.setScene(stem);
  if (o.threads > 0) omp_set_num_threads(o.threads);
  const std::filesystem::path own = o.outDir / info.ownFolder;
  setupLogging(o.check ? std::filesystem::path() : own / (info.name + ".log"), o.quiet || !info.ownFolder.empty(),
               o.restart.has_value());
  auto log = logger(info.name);

  ExitCode code = ExitCode::kOk;
  std::string status = "ok";
  try {
    ctx.scene = Config::load(o.scenePath, o.overrides);
    run(ctx);
    if (o.check) log->info("{}: scene is valid", o.scenePath.string());
    // For the documentation test: the keys this scene made the program read.
    if (const char* list = std::getenv("COSIM_LIST_KEYS"); list && *list) {
      std::ofstream keys(list, std::ios::app);
      for (const auto& k : ctx.scene.askedKeys()) keys << info.name << ' ' << k << '\n';
    }
  } catch (const ConfigError& e) {
    code = ExitCode::kBadInput;
    status = e.what();
  } catch (const InstabilityError& e) {
    code = e.code();
    status = e.what();
    ctx.summary.setFailure(e.info());
  } catch (const SimulationError& e) {
    code = e.code();
    status = e.what();
  } catch (const std::exception& e) {
    // A bug, not the user's fault: say so, so it gets reported rather than worked around.
    status = fmt::format("internal error (please report): {}", e.what());
    code = static_cast<ExitCode>(1);
  }
  if (code != ExitCode::kOk) log->error("{}", status);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!o.check) {
    // What every run costs, whatever its solver adds: its threads, its peak memory (and its children's,
    // for a coupler), and the bytes it left in its results folder.
    rusage self{}, children{};
    getrusage(RUSAGE_SELF, &self);
    getrusage(RUSAGE_CHILDREN, &children);
    ctx.summary.setCost("threads", static_cast<std::int64_t>(omp_get_max_threads()));
    ctx.summary.setCost("peak_memory_mb", static_cast<double>(self.ru_maxrss) / 1024.0);
    if (children.ru_maxrss > 0)
      ctx.summary.setCost("peak_memory_children_mb", static_cast<double>(children.ru_maxrss) / 1024.0);
    std::error_code ec;
    std::uintmax_t bytes = 0;
    if (std::filesystem::is_directory(o.outDir, ec))
      for (const auto& e : std::filesystem::recursive_directory_iterator(o.outDir, ec))
        if (e.is_regular_file(ec)) bytes += e.file_size(ec);
    ctx.summary.setCost("output_bytes", static_cast<std::int64_t>(bytes));
    if (!ctx.summary.cost().count("processes")) ctx.summary.setCost("processes", std::int64_t{1});
    try {
      ctx.summary.write(own / "summary.yaml", code, status, wall);
    } catch (const std::exception& e) {
      log->error("{}", e.what());
    }
  }
  spdlog::apply_all([](const std::shared_ptr<spdlog::logger>& l) { l->flush(); });
  return static_cast<int>(code);
}

}  // namespace common
