// The job report as one JSON object (facetree/grid.h).
#include <algorithm>

#include "facetree/grid.h"
#include "facetree/io.h"

namespace facetree {

std::string jobReportJson(const JobReport& r, const JobReportContext& context) {
  const double ratio = r.balancedHeight ? double(r.height) / r.balancedHeight : 0.0;
  const BuildStats& s = r.inCore;  // in-core jobs only
  JsonWriter json;
  json.field("mesh", context.mesh);
  json.field("out_of_core", r.outOfCore);
  json.field("triangles", r.triangles);
  json.field("vertices", r.stats.vertices);
  json.field("welded_vertices", r.weldedVertices);
  json.field("nodes", r.nodes);
  json.field("height", r.height);
  json.field("balanced_height", r.balancedHeight);
  json.field("height_ratio", ratio);
  json.field("components", r.components);
  json.field("order", orderName(context.order));
  if (!r.outOfCore) {
    json.field("rounds", s.rounds);
    json.field("average_degree", s.averageDegree);
    json.field("max_degree", s.maxDegree);
    json.field("eigen_solves", s.eigenSolves);
    json.field("normal_shortcuts", s.normalShortcuts);
  }
  json.field("cells", r.cells);
  json.field("leaves", r.leaves);
  json.field("cross_edges", r.crossEdges);
  json.field("upper_components", r.upperComponents);
  json.field("cell_face_limit", r.cellFaceLimit);
  json.field("read_ranges", r.readRanges);
  // "build" is the time from the start to the finished hierarchy; the others are phases.
  json.beginObject("seconds");
  json.field("read", r.secondsRead);
  if (r.outOfCore) {
    json.field("bin", r.secondsBin);
    json.field("cells", r.secondsCells);
    json.field("merge", r.secondsMerge);
  } else {
    json.field("init", s.secondsInit);
    json.field("cost", s.secondsCost);
    json.field("eigen", s.secondsEigen);
    json.field("merge", s.secondsMerge);
    json.field("boxes", s.secondsBoxes);
  }
  json.field("build", r.secondsBuilt);
  json.field("write", r.secondsWrite);
  json.field("total", r.seconds);
  json.endObject();
  json.beginObject("peak_rss_after");
  for (const auto& [phase, bytes] : r.peakRssAfter) json.field(phase, bytes);
  json.endObject();
  json.field("memory_cap_bytes", r.memoryCap);
  json.field("peak_rss_bytes",
             std::max(context.peakRssBytes, r.peakRssBytes));  // as tasks: the largest task's
  json.field("temporary_bytes_peak", r.temporaryBytesPeak);
  if (context.hasOutput) json.field("file_bytes", r.fileBytes);
  return json.finish();
}

}  // namespace facetree
