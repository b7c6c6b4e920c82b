#include "common/log.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>

namespace common {

namespace {

struct Sinks {
  std::mutex mutex;
  std::vector<spdlog::sink_ptr> sinks;
};

Sinks& sinks() {
  static Sinks s;
  return s;
}

std::vector<spdlog::sink_ptr> currentSinks() {
  Sinks& s = sinks();
  if (s.sinks.empty()) {
    auto console = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
    console->set_level(spdlog::level::info);
    console->set_pattern("[%n] %^%l%$: %v");
    s.sinks.push_back(console);
  }
  return s.sinks;
}

std::string formatDuration(double s) {
  if (s < 60) return fmt::format("{:.0f} s", s);
  if (s < 3600) return fmt::format("{:.0f} min {:02.0f} s", std::floor(s / 60), std::fmod(s, 60));
  return fmt::format("{:.0f} h {:02.0f} min", std::floor(s / 3600), std::fmod(s / 60, 60));
}

}  // namespace

void setupLogging(const std::filesystem::path& runLog, bool quiet, bool append) {
  Sinks& s = sinks();
  std::lock_guard lock(s.mutex);
  s.sinks.clear();
  auto console = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  console->set_level(quiet ? spdlog::level::warn : spdlog::level::info);
  console->set_pattern("[%n] %^%l%$: %v");
  s.sinks.push_back(console);
  if (!runLog.empty()) {
    if (runLog.has_parent_path()) std::filesystem::create_directories(runLog.parent_path());
    auto file = std::make_shared<spdlog::sinks::basic_file_sink_mt>(runLog.string(), !append);
    file->set_level(spdlog::level::debug);
    file->set_pattern("%Y-%m-%d %H:%M:%S.%e [%n] %l: %v");
    s.sinks.push_back(file);
  }
  spdlog::apply_all([&](const std::shared_ptr<spdlog::logger>& l) {
    l->sinks() = s.sinks;
    l->set_level(spdlog::level::debug);
    l->flush_on(spdlog::level::info);
  });
}

std::shared_ptr<spdlog::logger> logger(const std::string& name) {
  if (auto l = spdlog::get(name)) return l;
  auto sinkList = currentSinks();
  auto l = std::make_shared<spdlog::logger>(name, sinkList.begin(), sinkList.end());
  l->set_level(spdlog::level::debug);
  l->flush_on(spdlog::level::info);
  try {
    spdlog::register_logger(l);
  } catch (const spdlog::spdlog_ex&) {
    return spdlog::get(name);  // another thread registered it first
  }
  return l;
}

Progress::Progress(std::string label, double endTime, bool enabled, std::chrono::duration<double> logEvery)
    : label_(std::move(label)),
      endTime_(endTime),
      enabled_(enabled),
      terminal_(isatty(STDERR_FILENO) != 0),
      logEvery_(logEvery),
      start_(std::chrono::steady_clock::now()),
      lastPrint_(start_) {}

Progress::~Progress() {
  if (lineOpen_) std::fputc('\n', stderr);
}

std::string Progress::format(double time, double endTime, std::int64_t steps, double elapsed) {
  const double fraction = endTime > 0 ? std::clamp(time / endTime, 0.0, 1.0) : 1.0;
  const double rate = elapsed > 0 ? static_cast<double>(steps) / elapsed : 0.0;
  std::string eta = fraction > 0 ? formatDuration(elapsed * (1 - fraction) / fraction) : std::string("?");
  return fmt::format("t = {:.4g} / {:.4g} s ({:.1f} %), {} steps, {:.3g} steps/s, ETA {}", time, endTime,
                     100 * fraction, steps, rate, eta);
}

void Progress::update(double time, std::int64_t steps) {
  if (!enabled_ || (++calls_ & 63u) != 0) return;
  const auto now = std::chrono::steady_clock::now();
  const auto since = now - lastPrint_;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  if (terminal_) {
    if (since < std::chrono::milliseconds(200)) return;
    std::fprintf(stderr, "\r[%s] %s   ", label_.c_str(), format(time, endTime_, steps, elapsed).c_str());
    std::fflush(stderr);
    lineOpen_ = true;
  } else {
    if (since < logEvery_) return;
    logger(label_)->info("{}", format(time, endTime_, steps, elapsed));
  }
  lastPrint_ = now;
}

void Progress::finish(double time, std::int64_t steps) {
  if (lineOpen_) {
    std::fputc('\n', stderr);
    lineOpen_ = false;
  }
  if (!enabled_) return;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  logger(label_)->info("done: {} steps to t = {:.6g} s in {:.3f} s wall ({:.3g} steps/s)", steps, time, elapsed,
                       elapsed > 0 ? static_cast<double>(steps) / elapsed : 0.0);
}

}  // namespace common
