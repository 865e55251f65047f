// Pictures and coloured PLY exports of a clustering, decoded and checked pixel by pixel.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "error_expect.h"
#include "facetree/io.h"
#include "facetree/picture.h"
#include "picture/camera.h"
#include "picture/palette.h"
#include "picture/rasterizer.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wunused-but-set-variable"
#define STB_IMAGE_IMPLEMENTATION
#include <stb_image.h>
#undef STB_IMAGE_IMPLEMENTATION
#pragma GCC diagnostic pop

namespace facetree {
namespace {

struct TestMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint32_t> clusters;
  MeshView view() const { return {positions, indices}; }
  void add(uint32_t a, uint32_t b, uint32_t c, uint32_t cluster) {
    indices.insert(indices.end(), {a, b, c});
    clusters.push_back(cluster);
  }
};

// Unit square in z = 0 split along its diagonal: the lower-right triangle is cluster 10, the
// upper-left one cluster 11.
TestMesh square() {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.add(0, 1, 2, 10);
  mesh.add(0, 2, 3, 11);
  return mesh;
}

// Unit cube centred at the origin; each side is a cluster: +x 0, -x 1, +y 2, -y 3, +z 4, -z 5.
TestMesh cube() {
  TestMesh mesh;
  for (int i = 0; i < 8; ++i)
    mesh.positions.emplace_back((i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f);
  const auto quad = [&](uint32_t a, uint32_t b, uint32_t c, uint32_t d, uint32_t cluster) {
    mesh.add(a, b, c, cluster);
    mesh.add(a, c, d, cluster);
  };
  quad(1, 3, 7, 5, 0);
  quad(0, 4, 6, 2, 1);
  quad(2, 6, 7, 3, 2);
  quad(0, 1, 5, 4, 3);
  quad(4, 5, 7, 6, 4);
  quad(0, 2, 3, 1, 5);
  return mesh;
}

// Cluster id of a grid cell, spread so that neighbouring cells get unrelated ids.
uint32_t cellCluster(int i, int j, int k) {
  return static_cast<uint32_t>(i * 73856093 ^ j * 19349663 ^ k * 83492791) % 100003u;
}

// Height field over [0, 4] x [0, 3] with side x side quads; clusters are cells of size 0.4.
TestMesh terrain(int side) {
  TestMesh mesh;
  for (int j = 0; j <= side; ++j) {
    for (int i = 0; i <= side; ++i) {
      const float x = 4.0f * static_cast<float>(i) / static_cast<float>(side);
      const float y = 3.0f * static_cast<float>(j) / static_cast<float>(side);
      const float z = 0.35f * std::sin(1.7f * x) * std::cos(2.1f * y) + 0.12f * std::sin(5.3f * x + 3.1f * y);
      mesh.positions.emplace_back(x, y, z);
    }
  }
  const auto vertex = [&](int i, int j) { return static_cast<uint32_t>(j * (side + 1) + i); };
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      const uint32_t cluster = cellCluster(i * 10 / side, j * 10 / side, 0);
      mesh.add(vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1), cluster);
      mesh.add(vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1), cluster);
    }
  }
  return mesh;
}

// UV sphere of radius 1; clusters are cells of size 0.4 around the face centroids.
TestMesh sphere(int rings, int segments) {
  TestMesh mesh;
  for (int r = 0; r <= rings; ++r) {
    const float theta = std::numbers::pi_v<float> * static_cast<float>(r) / static_cast<float>(rings);
    for (int s = 0; s < segments; ++s) {
      const float phi =
          2.0f * std::numbers::pi_v<float> * static_cast<float>(s) / static_cast<float>(segments);
      mesh.positions.emplace_back(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                  std::cos(theta));
    }
  }
  const auto vertex = [&](int r, int s) { return static_cast<uint32_t>(r * segments + s % segments); };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      const glm::vec3 centre = (mesh.positions[vertex(r, s)] + mesh.positions[vertex(r + 1, s + 1)]) * 0.5f;
      const glm::ivec3 cell(glm::floor(centre / 0.4f));
      const uint32_t cluster = cellCluster(cell.x, cell.y, cell.z);
      // Triangles at the poles are degenerate (two vertices at the pole): rendering skips them.
      mesh.add(vertex(r, s), vertex(r + 1, s), vertex(r + 1, s + 1), cluster);
      mesh.add(vertex(r, s), vertex(r + 1, s + 1), vertex(r, s + 1), cluster);
    }
  }
  return mesh;
}

class Scratch {
 public:
  explicit Scratch(const std::string& name)
      : dir_(std::filesystem::temp_directory_path() /
             ("facetree_render_" + name + std::to_string(::getpid()))) {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~Scratch() { std::filesystem::remove_all(dir_); }
  std::filesystem::path operator/(const std::string& name) const { return dir_ / name; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

struct Image {
  int width = 0, height = 0;
  std::vector<glm::u8vec3> pixels;
  glm::u8vec3 at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

Image loadPng(const std::filesystem::path& path) {
  Image image;
  int channels = 0;
  std::unique_ptr<stbi_uc, decltype(&stbi_image_free)> data(
      stbi_load(path.c_str(), &image.width, &image.height, &channels, 3), &stbi_image_free);
  if (!data) throw std::runtime_error("cannot decode " + path.string());
  image.pixels.resize(static_cast<size_t>(image.width) * image.height);
  std::memcpy(image.pixels.data(), data.get(), image.pixels.size() * 3);
  return image;
}

// Which of `clusters` a pixel shows: its colour must be the cluster's palette colour times a
// shade, within rounding. Returns -1 for background, outlines and anything else.
int classify(glm::u8vec3 pixel, const std::vector<uint32_t>& clusters) {
  constexpr float kTolerance = 4.0f;
  const glm::vec3 p(pixel);
  for (size_t i = 0; i < clusters.size(); ++i) {
    const glm::vec3 c(clusterColour(clusters[i]));
    const float scale = glm::dot(p, c) / glm::dot(c, c);
    if (scale > 0.2f && scale < 1.01f && glm::length(p - scale * c) < kTolerance) return static_cast<int>(i);
  }
  return -1;
}

std::vector<size_t> countClusters(const Image& image, const std::vector<uint32_t>& clusters) {
  std::vector<size_t> counts(clusters.size(), 0);
  for (const glm::u8vec3& pixel : image.pixels) {
    const int which = classify(pixel, clusters);
    if (which >= 0) ++counts[static_cast<size_t>(which)];
  }
  return counts;
}

void expectBackgroundCorners(const Image& image) {
  const glm::u8vec3 background = image.at(0, 0);
  EXPECT_EQ(background.r, background.g);
  EXPECT_EQ(background.g, background.b);
  EXPECT_GE(background.r, 230) << "white or light grey";
  EXPECT_EQ(image.at(image.width - 1, 0), background);
  EXPECT_EQ(image.at(0, image.height - 1), background);
  EXPECT_EQ(image.at(image.width - 1, image.height - 1), background);
}

// Centroid of the pixels that differ from the background (the top-left corner).
glm::vec2 modelCentroid(const Image& image) {
  const glm::u8vec3 background = image.at(0, 0);
  glm::dvec2 sum(0.0);
  size_t count = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (image.at(x, y) == background) continue;
      sum += glm::dvec2(x + 0.5, y + 0.5);
      ++count;
    }
  }
  return count ? glm::vec2(sum / static_cast<double>(count)) : glm::vec2(-1.0f);
}

TEST(Palette, IsDeterministicAndSeparatesConsecutiveIds) {
  EXPECT_EQ(clusterColour(12345), clusterColour(12345));
  float closest = 1e9f;
  for (uint32_t id = 0; id < 100000; ++id) {
    const glm::vec3 a(clusterColour(id)), b(clusterColour(id + 1));
    closest = std::min(closest, glm::length(a - b));
    const float spread = std::max({a.r, a.g, a.b}) - std::min({a.r, a.g, a.b});
    ASSERT_GE(spread, 90.0f) << "cluster " << id << " is too grey";
  }
  EXPECT_GT(closest, 120.0f) << "consecutive ids must get clearly different colours";
  EXPECT_NE(clusterColour(0xFFFFFFFFu), clusterColour(0));
}

TEST(Camera, DefaultViewLooksDownAndFallsBackFromParallelUp) {
  const ViewBasis basis = makeViewBasis(glm::vec3(0.0f), glm::vec3(0, 0, 1));
  EXPECT_LT(basis.forward.z, -0.3f) << "the default view looks down at the model";
  EXPECT_GT(basis.up.z, 0.5f);
  const ViewBasis top = makeViewBasis(glm::vec3(0, 0, -2), glm::vec3(0, 0, 1));
  EXPECT_NEAR(glm::length(top.up - glm::vec3(0, 1, 0)), 0.0f, 1e-6f)
      << "up parallel to the view falls back to +y";
  for (const ViewBasis& b : {basis, top}) {
    EXPECT_NEAR(glm::length(b.right), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::length(b.up), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(b.right, b.up), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(b.up, b.forward), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(b.right, b.forward), 0.0f, 1e-5f);
  }
}

TEST(Rasterizer, SharedEdgesLeaveNoGaps) {
  // A jittered grid of triangles over [10.3, 90.7]^2: every sample centre inside is covered.
  constexpr int kSide = 23;
  SampleBuffer buffer(100, 100);
  std::vector<glm::vec3> points;
  for (int j = 0; j <= kSide; ++j) {
    for (int i = 0; i <= kSide; ++i) {
      const bool border = i == 0 || j == 0 || i == kSide || j == kSide;
      const float jitterX = border ? 0.0f : 0.37f * std::sin(static_cast<float>(i * 7 + j * 13));
      const float jitterY = border ? 0.0f : 0.37f * std::cos(static_cast<float>(i * 11 + j * 5));
      const float step = 80.4f / kSide;
      points.emplace_back(10.3f + step * (static_cast<float>(i) + jitterX),
                          10.3f + step * (static_cast<float>(j) + jitterY), 1.0f);
    }
  }
  const auto at = [&](int i, int j) { return points[static_cast<size_t>(j * (kSide + 1) + i)]; };
  for (int j = 0; j < kSide; ++j) {
    for (int i = 0; i < kSide; ++i) {
      buffer.drawTriangle(at(i, j), at(i + 1, j), at(i + 1, j + 1), 1, 255);
      buffer.drawTriangle(at(i, j), at(i, j + 1), at(i + 1, j + 1), 1, 255);  // opposite winding
    }
  }
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 100; ++x) {
      const bool inside = x + 0.5f > 10.3f && x + 0.5f < 90.7f && y + 0.5f > 10.3f && y + 0.5f < 90.7f;
      EXPECT_EQ(buffer.covered(static_cast<size_t>(y * 100 + x)), inside) << x << "," << y;
    }
  }
}

TEST(Rasterizer, NearerTriangleWins) {
  SampleBuffer buffer(8, 8);
  buffer.drawTriangle({0, 0, 5}, {8, 0, 5}, {0, 8, 5}, 1, 100);
  buffer.drawTriangle({0, 0, 2}, {8, 0, 2}, {0, 8, 2}, 2, 200);
  buffer.drawTriangle({0, 0, 9}, {8, 0, 9}, {0, 8, 9}, 3, 50);
  EXPECT_EQ(buffer.cluster(0), 2u);
  EXPECT_EQ(buffer.shade(0), 200);
  EXPECT_FALSE(buffer.covered(63));
}

TEST(RenderClustersPng, SquareFromAboveShowsBothHalvesEqually) {
  Scratch scratch("square");
  const TestMesh mesh = square();
  RenderOptions options;
  options.viewDirection = glm::vec3(0, 0, -1);
  options.up = glm::vec3(0, 1, 0);
  const auto path = scratch / "square.png";
  renderClustersPng(mesh.view(), mesh.clusters, options, path);
  const Image image = loadPng(path);
  ASSERT_EQ(image.width, 1024);
  ASSERT_EQ(image.height, 768);
  expectBackgroundCorners(image);
  const auto counts = countClusters(image, {10, 11});
  // The square fills 90% of the height: about 691^2 pixels, half each.
  EXPECT_NEAR(static_cast<double>(counts[0] + counts[1]), 691.0 * 691.0, 0.03 * 691.0 * 691.0);
  EXPECT_NEAR(static_cast<double>(counts[0]) / static_cast<double>(counts[1]), 1.0, 0.02);
  // Cluster 10 is the lower-right triangle (x > y), seen from above with +y up.
  EXPECT_EQ(classify(image.at(512 + 200, 384 + 100), {10, 11}), 0);
  EXPECT_EQ(classify(image.at(512 - 200, 384 - 100), {10, 11}), 1);
  const glm::vec2 centroid = modelCentroid(image);
  EXPECT_NEAR(centroid.x, 512.0f, 2.0f);
  EXPECT_NEAR(centroid.y, 384.0f, 2.0f);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(scratch.dir()), {}), 1) << "no temporary left";
}

TEST(RenderClustersPng, CubeShowsThreeSidesInProportionToTheirProjectedArea) {
  Scratch scratch("cube");
  const TestMesh mesh = cube();
  const auto path = scratch / "cube.png";
  RenderOptions options;
  options.width = 800;
  options.height = 600;
  renderClustersPng(mesh.view(), mesh.clusters, options, path);
  const Image image = loadPng(path);
  ASSERT_EQ(image.width, 800);
  ASSERT_EQ(image.height, 600);
  expectBackgroundCorners(image);
  const auto counts = countClusters(image, {0, 1, 2, 3, 4, 5});
  // Default view direction is along (-1, -1.3, -0.8): +x, +y and +z face the camera and their
  // orthographic projected areas are proportional to 1 : 1.3 : 0.8.
  EXPECT_EQ(counts[1] + counts[3] + counts[5], 0u) << "hidden sides";
  const double visible = static_cast<double>(counts[0] + counts[2] + counts[4]);
  ASSERT_GT(visible, 0.2 * 800 * 600);
  EXPECT_NEAR(counts[0] / visible, 1.0 / 3.1, 0.02);
  EXPECT_NEAR(counts[2] / visible, 1.3 / 3.1, 0.02);
  EXPECT_NEAR(counts[4] / visible, 0.8 / 3.1, 0.02);
  // A convex body's orthographic outline is centrally symmetric.
  const glm::vec2 centroid = modelCentroid(image);
  EXPECT_NEAR(centroid.x, 400.0f, 2.0f);
  EXPECT_NEAR(centroid.y, 300.0f, 2.0f);
  // Outlines: the pixel between the +x and +y sides along the vertical edge is darker than both.
  size_t dark = 0;
  for (const glm::u8vec3& p : image.pixels) dark += (p.r < 90 && p.g < 90 && p.b < 90);
  EXPECT_GT(dark, 1000u) << "cluster boundaries and silhouette are outlined";
}

TEST(RenderClustersPng, SkipsDegenerateAndNonFiniteTriangles) {
  Scratch scratch("degenerate");
  const TestMesh plain = square();
  TestMesh messy = square();
  messy.positions.push_back({0.5f, 0.5f, 0.0f});
  messy.positions.push_back({std::nanf(""), 0.0f, 0.0f});
  messy.positions.push_back({INFINITY, 1.0f, 0.0f});
  messy.add(0, 4, 2, 99);  // collinear: on the diagonal
  messy.add(1, 1, 1, 99);  // a point
  messy.add(0, 5, 1, 99);  // NaN vertex
  messy.add(6, 2, 3, 99);  // infinite vertex
  RenderOptions options;
  options.viewDirection = glm::vec3(0, 0, -1);
  renderClustersPng(plain.view(), plain.clusters, options, scratch / "plain.png");
  renderClustersPng(messy.view(), messy.clusters, options, scratch / "messy.png");
  EXPECT_EQ(loadPng(scratch / "plain.png").pixels, loadPng(scratch / "messy.png").pixels);
}

TEST(RenderClustersPng, EmptyMeshGivesBackgroundOnly) {
  Scratch scratch("empty");
  RenderOptions options;
  options.width = 64;
  options.height = 48;
  renderClustersPng(MeshView{}, {}, options, scratch / "empty.png");
  const Image image = loadPng(scratch / "empty.png");
  ASSERT_EQ(image.width, 64);
  for (const glm::u8vec3& p : image.pixels) ASSERT_EQ(p, image.at(0, 0));
}

TEST(RenderClustersPng, RejectsBadInput) {
  Scratch scratch("bad");
  TestMesh mesh = square();
  const auto path = scratch / "bad.png";
  const std::vector<uint32_t> oneCluster = {1};
  EXPECT_THROW(renderClustersPng(mesh.view(), oneCluster, {}, path), std::invalid_argument);
  RenderOptions zero;
  zero.width = 0;
  EXPECT_THROW(renderClustersPng(mesh.view(), mesh.clusters, zero, path), std::invalid_argument);
  mesh.indices[4] = 4;
  try {
    renderClustersPng(mesh.view(), mesh.clusters, {}, path);
    FAIL() << "index out of range accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("vertex 4"), std::string::npos) << error.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(RenderClustersPng, UnwritablePathThrowsIoErrorAndLeavesNothing) {
  Scratch scratch("unwritable");
  const TestMesh mesh = square();
  EXPECT_FACETREE_ERROR(renderClustersPng(mesh.view(), mesh.clusters, {}, scratch / "missing" / "out.png"),
                        Output);
  EXPECT_FALSE(std::filesystem::exists(scratch / "missing"));
  // The target is a directory: the rename fails and the temporary is removed.
  std::filesystem::create_directories(scratch / "taken.png" / "child");
  EXPECT_FACETREE_ERROR(renderClustersPng(mesh.view(), mesh.clusters, {}, scratch / "taken.png"), Output);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(scratch.dir()), {}), 1);
}

// Renders a million-triangle terrain and a sphere (the picture is centred, the corners are
// background; render speed is measured by scripts/bench, not here); with
// FACETREE_RENDER_CHECK_DIR set the pictures are kept there to be looked at.
TEST(RenderClustersPng, MillionTrianglesRenderCentred) {
  Scratch scratch("large");
  const char* keep = std::getenv("FACETREE_RENDER_CHECK_DIR");
  const std::filesystem::path dir = keep ? std::filesystem::path(keep) : scratch.dir();
  // The picture of `mesh` has background corners and the model's centroid within `tolerance`
  // pixels of the centre of the 1024 x 768 picture.
  const auto expectCentred = [&](const TestMesh& mesh, const char* name, float tolerance) {
    renderClustersPng(mesh.view(), mesh.clusters, {}, dir / name);
    const Image image = loadPng(dir / name);
    expectBackgroundCorners(image);
    const glm::vec2 centroid = modelCentroid(image);
    EXPECT_NEAR(centroid.x, 512.0f, tolerance) << name;
    EXPECT_NEAR(centroid.y, 384.0f, tolerance) << name;
  };
  const TestMesh land = terrain(708);
  ASSERT_GE(land.clusters.size(), 1000000u);
  expectCentred(land, "terrain.png", 60.0f);
  expectCentred(sphere(200, 400), "sphere.png", 2.0f);
  const TestMesh box = cube();
  renderClustersPng(box.view(), box.clusters, {}, dir / "cube.png");
  writeClusterColouredPly(land.view(), land.clusters, dir / "terrain.ply");
}

// Reads a PLY written by writeClusterColouredPly: header lines, then the binary body.
struct ParsedPly {
  std::vector<std::string> header;
  std::vector<glm::vec3> positions;
  std::vector<std::array<int32_t, 3>> faces;
  std::vector<glm::u8vec3> colours;
};

ParsedPly readColouredPly(const std::filesystem::path& path, size_t vertices, size_t faces) {
  std::ifstream in(path, std::ios::binary);
  ParsedPly ply;
  std::string line;
  while (std::getline(in, line)) {
    ply.header.push_back(line);
    if (line == "end_header") break;
  }
  ply.positions.resize(vertices);
  in.read(reinterpret_cast<char*>(ply.positions.data()), static_cast<std::streamsize>(vertices * 12));
  for (size_t f = 0; f < faces; ++f) {
    unsigned char record[16];
    in.read(reinterpret_cast<char*>(record), sizeof record);
    EXPECT_EQ(record[0], 3);
    std::array<int32_t, 3> face;
    std::memcpy(face.data(), record + 1, 12);
    ply.faces.push_back(face);
    ply.colours.emplace_back(record[13], record[14], record[15]);
  }
  EXPECT_TRUE(in.good());
  EXPECT_EQ(in.peek(), std::char_traits<char>::eof()) << "nothing after the faces";
  return ply;
}

TEST(WriteClusterColouredPly, WritesPaletteColoursPerFace) {
  Scratch scratch("ply");
  const TestMesh mesh = cube();
  const auto path = scratch / "cube.ply";
  writeClusterColouredPly(mesh.view(), mesh.clusters, path);
  const ParsedPly ply = readColouredPly(path, 8, 12);
  const std::vector<std::string> expectedHeader = {"ply",
                                                   "format binary_little_endian 1.0",
                                                   "comment facetree clusters",
                                                   "element vertex 8",
                                                   "property float x",
                                                   "property float y",
                                                   "property float z",
                                                   "element face 12",
                                                   "property list uchar int vertex_indices",
                                                   "property uchar red",
                                                   "property uchar green",
                                                   "property uchar blue",
                                                   "end_header"};
  EXPECT_EQ(ply.header, expectedHeader);
  EXPECT_EQ(ply.positions, mesh.positions);
  std::map<uint32_t, glm::u8vec3> byCluster;
  for (size_t f = 0; f < 12; ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(ply.faces[f][k], static_cast<int32_t>(mesh.indices[3 * f + k]));
    EXPECT_EQ(ply.colours[f], clusterColour(mesh.clusters[f]));
    const auto [it, inserted] = byCluster.emplace(mesh.clusters[f], ply.colours[f]);
    EXPECT_EQ(it->second, ply.colours[f]) << "faces of one cluster share a colour";
  }
  EXPECT_EQ(byCluster.size(), 6u);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(scratch.dir()), {}), 1) << "no temporary left";
}

TEST(WriteClusterColouredPly, RejectsBadInputAndUnwritablePaths) {
  Scratch scratch("plybad");
  TestMesh mesh = cube();
  const auto path = scratch / "bad.ply";
  const std::vector<uint32_t> tooMany(13, 0);
  EXPECT_THROW(writeClusterColouredPly(mesh.view(), tooMany, path), std::invalid_argument);
  EXPECT_FACETREE_ERROR(writeClusterColouredPly(mesh.view(), mesh.clusters, scratch / "missing" / "x.ply"),
                        Output);
  mesh.indices[7] = 8;
  EXPECT_THROW(writeClusterColouredPly(mesh.view(), mesh.clusters, path), std::invalid_argument);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(scratch.dir()), {}), 0);
}

}  // namespace
}  // namespace facetree
