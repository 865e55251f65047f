// Flat-shaded software rendering of a clustering to PNG.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "camera.h"
#include "facetree/picture.h"
#include "palette.h"
#include "rasterizer.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace facetree {
namespace {
constexpr int kSupersample = 2;       // samples per pixel along each axis, box filtered
constexpr int kMaxImageSide = 16384;  // pixels
constexpr int kChannels = 3;          // RGB
constexpr float kAmbient = 0.40f;     // shade = ambient + diffuse * |cos(normal, light)|
constexpr float kDiffuse = 0.60f;
// Towards the light in view space (right, up, towards the camera): a headlight raised a little
// and moved left so faces at different angles get different shades.
constexpr glm::vec3 kLightInView{-0.35f, 0.5f, 1.0f};
constexpr glm::vec3 kBackground{248.0f, 248.0f, 248.0f};
constexpr glm::vec3 kEdgeColour{25.0f, 25.0f, 30.0f};
constexpr float kEdgeStrength = 0.8f;  // of a sample on a cluster boundary or the silhouette

void checkOptions(const RenderOptions& options) {
  if (options.width < 1 || options.height < 1 || options.width > kMaxImageSide ||
      options.height > kMaxImageSide)
    throw std::invalid_argument("renderClustersPng: image size " + std::to_string(options.width) + "x" +
                                std::to_string(options.height) + " is outside 1.." +
                                std::to_string(kMaxImageSide));
}

void rasterize(const MeshView& mesh, std::span<const uint32_t> faceCluster, std::span<const glm::vec3> points,
               SampleBuffer& buffer) {
  // Sample space flips y and keeps x and depth: the light direction follows.
  const glm::vec3 light = glm::normalize(glm::vec3(kLightInView.x, -kLightInView.y, -kLightInView.z));
  const size_t triangles = mesh.triangleCount();
  // Each vertex snapped once; a triangle whose bounds hold no sample (most, in a mesh far finer
  // than the picture) is left before its shade.
  std::vector<SampleBuffer::Snapped> snapped(points.size());
  for (size_t v = 0; v < points.size(); ++v)
    if (isFinite(points[v])) snapped[v] = SampleBuffer::snap(points[v]);
  for (size_t t = 0; t < triangles; ++t) {
    const uint32_t ia = mesh.indices[3 * t], ib = mesh.indices[3 * t + 1], ic = mesh.indices[3 * t + 2];
    const glm::vec3& a = points[ia];
    const glm::vec3& b = points[ib];
    const glm::vec3& c = points[ic];
    if (!isFinite(a) || !isFinite(b) || !isFinite(c)) continue;
    if (!buffer.boundsHoldASample(snapped[ia], snapped[ib], snapped[ic])) continue;
    const glm::vec3 normal = glm::cross(b - a, c - a);
    const float length = glm::length(normal);
    if (!(length > 0.0f) || !std::isfinite(length)) continue;  // degenerate
    // Two-sided: meshes are not always consistently oriented.
    const float shade = kAmbient + kDiffuse * std::min(std::abs(glm::dot(normal, light)) / length, 1.0f);
    buffer.drawSnapped(snapped[ia], snapped[ib], snapped[ic], faceCluster[t],
                       static_cast<uint8_t>(std::lround(shade * 255.0f)));
  }
}

// Box-filters the samples to RGB pixels; samples next to a different cluster, or on the
// boundary between model and background, are darkened into thin outlines.
std::vector<unsigned char> resolve(const SampleBuffer& buffer, int width, int height) {
  const int sampleWidth = buffer.width(), sampleHeight = buffer.height();
  const auto differs = [&](size_t i, size_t j) {
    return buffer.covered(i) != buffer.covered(j) ||
           (buffer.covered(i) && buffer.cluster(i) != buffer.cluster(j));
  };
  uint32_t cachedCluster = 0;
  glm::vec3 cachedColour = glm::vec3(clusterColour(0));
  const auto sampleColour = [&](int x, int y) {
    const size_t i = static_cast<size_t>(y) * static_cast<size_t>(sampleWidth) + static_cast<size_t>(x);
    glm::vec3 colour = kBackground;
    if (buffer.covered(i)) {
      if (buffer.cluster(i) != cachedCluster) {
        cachedCluster = buffer.cluster(i);
        cachedColour = glm::vec3(clusterColour(cachedCluster));
      }
      colour = cachedColour * (static_cast<float>(buffer.shade(i)) / 255.0f);
    }
    const bool boundary = (x > 0 && differs(i, i - 1)) || (x + 1 < sampleWidth && differs(i, i + 1)) ||
                          (y > 0 && differs(i, i - static_cast<size_t>(sampleWidth))) ||
                          (y + 1 < sampleHeight && differs(i, i + static_cast<size_t>(sampleWidth)));
    return boundary ? glm::mix(colour, kEdgeColour, kEdgeStrength) : colour;
  };

  std::vector<unsigned char> pixels(static_cast<size_t>(width) * static_cast<size_t>(height) * kChannels);
  constexpr float kWeight = 1.0f / (kSupersample * kSupersample);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      glm::vec3 sum(0.0f);
      for (int sy = 0; sy < kSupersample; ++sy)
        for (int sx = 0; sx < kSupersample; ++sx)
          sum += sampleColour(x * kSupersample + sx, y * kSupersample + sy);
      const glm::vec3 pixel = glm::clamp(glm::round(sum * kWeight), 0.0f, 255.0f);
      unsigned char* out =
          &pixels[(static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)) * kChannels];
      out[0] = static_cast<unsigned char>(pixel.r);
      out[1] = static_cast<unsigned char>(pixel.g);
      out[2] = static_cast<unsigned char>(pixel.b);
    }
  }
  return pixels;
}

std::vector<unsigned char> encodePng(std::span<const uint8_t> pixels, int width, int height,
                                     const std::filesystem::path& path) {
  std::vector<unsigned char> png;
  const auto append = [](void* context, void* data, int size) {
    auto* bytes = static_cast<unsigned char*>(data);
    static_cast<std::vector<unsigned char>*>(context)->insert(
        static_cast<std::vector<unsigned char>*>(context)->end(), bytes, bytes + size);
  };
  if (stbi_write_png_to_func(append, &png, width, height, kChannels, pixels.data(), width * kChannels) == 0)
    throw Error(ErrorCategory::Output, path.string() + ": cannot encode PNG");
  return png;
}
}  // namespace

void writePng(const std::filesystem::path& path, std::span<const uint8_t> rgb, int width, int height) {
  if (width <= 0 || height <= 0 || rgb.size() != size_t{3} * width * height)
    throw std::invalid_argument("writePng: " + std::to_string(rgb.size()) + " bytes for " +
                                std::to_string(width) + "x" + std::to_string(height) + " pixels");
  const std::vector<unsigned char> png = encodePng(rgb, width, height, path);
  OutputFile out(path);
  out.write(png.data(), png.size());
  out.commit();
}

void renderClustersPng(const MeshView& mesh, std::span<const uint32_t> faceCluster,
                       const RenderOptions& options, const std::filesystem::path& path) {
  checkOptions(options);
  checkClusterMesh(mesh, faceCluster, "renderClustersPng");
  const int sampleWidth = options.width * kSupersample, sampleHeight = options.height * kSupersample;
  const ViewBasis basis = makeViewBasis(options.viewDirection, options.up);
  const std::vector<glm::vec3> points =
      toSampleSpace(mesh.positions, mesh.indices, basis, sampleWidth, sampleHeight);
  SampleBuffer buffer(sampleWidth, sampleHeight);
  rasterize(mesh, faceCluster, points, buffer);
  writePng(path, resolve(buffer, options.width, options.height), options.width, options.height);
}

void renderClustersPng(ClusterFileReader& reader, std::span<const CutCluster> cut,
                       const RenderOptions& options, const std::filesystem::path& path) {
  checkOptions(options);
  const int sampleWidth = options.width * kSupersample, sampleHeight = options.height * kSupersample;
  // Two passes over the vertices fit the camera as toSampleSpace does; the triangles then come a
  // frame at a time with their own vertices.
  SampleSpace space(makeViewBasis(options.viewDirection, options.up), sampleWidth, sampleHeight);
  reader.forEachVertexFrame(
      [&](uint64_t, std::span<const glm::vec3> positions) { space.addBounds(positions); });
  reader.forEachVertexFrame(
      [&](uint64_t, std::span<const glm::vec3> positions) { space.addExtent(positions); });
  SampleBuffer buffer(sampleWidth, sampleHeight);
  std::vector<glm::vec3> points;
  reader.forEachCutPiece(
      cut,
      [&](const FaceRangeMesh& piece, std::span<const uint32_t> clusterOf) {
        points.resize(piece.vertices.size());
        for (size_t v = 0; v < points.size(); ++v) points[v] = space.map(piece.vertices[v]);
        rasterize(MeshView{piece.vertices, piece.indices}, clusterOf, points, buffer);
      },
      FaceFields::Geometry);
  writePng(path, resolve(buffer, options.width, options.height), options.width, options.height);
}

}  // namespace facetree
