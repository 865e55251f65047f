// A picture by ray casting (facetree/query.h): one orthographic ray per pixel through the
// hierarchy, shaded by the hit triangle's angle to the view. Orthographic, as the rasterized
// pictures are (io): the file's bounding box frames the same way whatever its size or place.
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "facetree/picture.h"

namespace facetree {

void renderRaycastPng(ClusterFileReader& reader, const RenderOptions& options,
                      const std::filesystem::path& path, const QueryOptions& queryOptions,
                      QueryStats* stats) {
  if (options.width < 1 || options.height < 1 || options.width > 16384 || options.height > 16384)
    throw std::invalid_argument("renderRaycastPng: width and height must be 1 to 16384");
  const ViewBasis basis = makeViewBasis(options.viewDirection, options.up);
  const FileHeader& header = reader.header();
  const glm::vec3 lo = header.boundsMin, hi = header.boundsMax, centre = 0.5f * (lo + hi);
  // The box's extent across the view, and its depth along it.
  float halfRight = 0, halfUp = 0, depth = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::vec3 p(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z);
    const glm::vec3 d = p - centre;
    halfRight = std::max(halfRight, std::abs(glm::dot(d, basis.right)));
    halfUp = std::max(halfUp, std::abs(glm::dot(d, basis.up)));
    depth = std::max(depth, std::abs(glm::dot(d, basis.forward)));
  }
  // Pixels square, the box filling the picture but for a margin of 5%.
  const float pixel = 1.1f * std::max(2 * halfRight / options.width, 2 * halfUp / options.height);
  const float size = pixel > 0 ? pixel : 1.0f;
  // The rays in tiles of 16 x 16 pixels, tile by tile: neighbouring rays visit the same nodes, so
  // that a batch's block of rays works in a few pages of a file read lazily. The rays are made and
  // cast in batches of 256 tiles, so that what they hold stays a few MB whatever the picture's size.
  constexpr int kTile = 16;
  constexpr size_t kBatchTiles = 256;
  const int tilesAcross = (options.width + kTile - 1) / kTile;
  const size_t tiles = size_t{1} * tilesAcross * ((options.height + kTile - 1) / kTile);
  const glm::vec3 start = centre - basis.forward * (depth + size);
  std::vector<uint8_t> rgb(size_t{3} * options.width * options.height, 255);
  std::vector<Ray> rays;
  std::vector<size_t> pixelOf;
  ReaderQueryIndex index(reader);  // one pass over the nodes for every batch
  for (size_t firstTile = 0; firstTile < tiles; firstTile += kBatchTiles) {
    rays.clear(), pixelOf.clear();
    for (size_t tile = firstTile; tile < std::min(tiles, firstTile + kBatchTiles); ++tile) {
      const int tx = static_cast<int>(tile % tilesAcross) * kTile,
                ty = static_cast<int>(tile / tilesAcross) * kTile;
      for (int y = ty; y < std::min(ty + kTile, options.height); ++y)
        for (int x = tx; x < std::min(tx + kTile, options.width); ++x) {
          Ray r;
          r.origin = start + basis.right * ((x + 0.5f - 0.5f * options.width) * size) +
                     basis.up * ((0.5f * options.height - y - 0.5f) * size);
          r.direction = basis.forward;
          rays.push_back(r);
          pixelOf.push_back(size_t{1} * y * options.width + x);
        }
    }
    const std::vector<RayHit> hits = intersect(index, rays, queryOptions, stats);
    for (size_t r = 0; r < hits.size(); ++r) {
      if (hits[r].face == kNoHit) continue;
      const float length = glm::length(hits[r].normal);
      const float facing = length > 0 ? std::abs(glm::dot(hits[r].normal, basis.forward)) / length : 0.0f;
      const auto grey = static_cast<uint8_t>(std::lround(40.0f + 190.0f * facing));
      const size_t i = pixelOf[r];
      rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = grey;
    }
  }
  writePng(path, rgb, options.width, options.height);
}

}  // namespace facetree
