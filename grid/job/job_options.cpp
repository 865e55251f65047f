// The build options by name (facetree/grid.h), and the process's peak resident set.
#include "facetree/grid.h"

#include <sys/resource.h>

#include <algorithm>
#include <initializer_list>
#include <stdexcept>
#include <thread>
#include <utility>

namespace facetree {
namespace {

// `name` (snake case) as `spelling` writes an option.
std::string optionName(std::string name, OptionSpelling spelling) {
  if (spelling == OptionSpelling::Python) return name;
  std::replace(name.begin(), name.end(), '_', '-');
  return "--" + name;
}

// The names of the options' values, as both directions use them.
template <typename T>
using Names = std::initializer_list<std::pair<const char*, T>>;
const Names<Metric> kMetricNames = {
    {"willmott", Metric::Willmott}, {"garland", Metric::Garland}, {"constant", Metric::Constant}};
const Names<MergeOrder> kOrderNames = {{"rounds", MergeOrder::Rounds}, {"exact", MergeOrder::Exact}};
const Names<BoxPrecision> kBoxesNames = {{"exact", BoxPrecision::Exact}, {"compact", BoxPrecision::Compact}};
const Names<RecastRule> kRecastNames = {{"largest-area", RecastRule::LargestArea},
                                        {"fewest-nodes", RecastRule::FewestNodes}};

// The value called `name` among `values`; "unknown WHAT 'NAME' (a, b, c)" otherwise.
template <typename T>
T named(const char* what, const std::string& name, Names<T> values) {
  std::string known;
  for (const auto& [text, value] : values) {
    if (name == text) return value;
    known += (known.empty() ? "" : ", ") + std::string(text);
  }
  throw std::invalid_argument("unknown " + std::string(what) + " '" + name + "' (" + known + ")");
}

// The name of `value` among `values`.
template <typename T>
const char* nameOf(T value, Names<T> values) {
  for (const auto& [text, known] : values)
    if (known == value) return text;
  return "unknown";
}

}  // namespace

void applyBuildSettings(const BuildSettings& s, OptionSpelling spelling, BuildOptions& build,
                        FileOptions& file) {
  const auto fail = [spelling](const char* option, const std::string& rule) {
    throw std::invalid_argument(optionName(option, spelling) + " " + rule);
  };
  build.metric = named("metric", s.metric, kMetricNames);
  build.order = named("merge order", s.order, kOrderNames);
  build.boxes = named("box precision", s.boxes, kBoxesNames);
  if (s.threads > kMaxJobThreads)
    fail("threads", "must be 0 (all cores) to " + std::to_string(kMaxJobThreads));
  if (!(s.balanceSlack >= 0)) fail("balance_slack", "must be 0 (off) or positive");
  if (!(s.k >= 0)) fail("k", "must not be negative");
  if (s.branching != 2 && s.branching != 4 && s.branching != 8) fail("branching", "must be 2, 4 or 8");
  file.rule = named("recast rule", s.recast, kRecastNames);
  build.k = s.k;
  build.flatThreshold = s.flatThreshold;
  build.balanceSlack = s.balanceSlack;
  build.garlandFitWeight = s.garlandWeights[0];
  build.garlandDirWeight = s.garlandWeights[1];
  build.garlandShapeWeight = s.garlandWeights[2];
  build.threads = s.threads;
  build.topClusters = s.top;
  file.branching = s.branching;
  file.build = build;
}

const char* metricName(Metric metric) {
  return nameOf(metric, kMetricNames);
}
const char* orderName(MergeOrder order) {
  return nameOf(order, kOrderNames);
}
const char* boxesName(BoxPrecision boxes) {
  return nameOf(boxes, kBoxesNames);
}

void checkJobLimits(uint64_t memoryCap, int zstdLevel, OptionSpelling spelling) {
  if (zstdLevel < 0 || zstdLevel > 19)
    throw std::invalid_argument(optionName("zstd_level", spelling) + " must be 1 to 19 (default 3)");
  if (memoryCap != 0 && memoryCap < (uint64_t{16} << 20))
    throw std::invalid_argument(optionName("memory", spelling) + " must be at least 16M");
}

unsigned jobThreads(unsigned requested) {
  return requested ? requested : std::clamp(std::thread::hardware_concurrency(), 1u, kMaxJobThreads);
}

uint64_t peakResidentBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<uint64_t>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

}  // namespace facetree
