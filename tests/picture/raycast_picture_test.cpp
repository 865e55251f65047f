// render --raycast's picture (renderRaycastPng): a sphere through a lazy reader, looked at along an
// axis, is a disc of grey pixels (brightest at the centre, where it faces the view) on white, of the
// area the sphere's outline covers; and the command line's render --raycast writes it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include <unistd.h>

#include <stb_image.h>  // its implementation is render_test.cpp's

#include "facetree/picture.h"
#include "facetree/query.h"
#include "merge/test_meshes.h"
#include "tests/cli/run_cli.h"
#include "tests/query/query_test_util.h"

namespace facetree {
namespace {

TEST(RaycastPicture, ASphereIsAGreyDiscBrightestAtItsCentre) {
  const test::TestMesh sphere = test::icosphere(4);
  const MeshView view{sphere.positions, sphere.indices};
  BuildOptions build;
  const ClusterFile file = makeClusterFile(view, {}, buildHierarchy(view, build), FileOptions{});
  test::TemporaryFiles files;
  const auto fch = files.add("raycast.fch"), png = files.add("raycast.png"),
             cli = files.add("raycast_cli.png");
  writeClusterFile(fch, file);
  ClusterFileReader reader(fch, ReaderOptions{1 << 20, {}});
  RenderOptions options;
  options.width = options.height = 101;
  options.viewDirection = {0, 0, -1};
  options.up = {0, 1, 0};
  QueryStats stats;
  renderRaycastPng(reader, options, png, {2}, &stats);
  int width = 0, height = 0, channels = 0;
  const std::unique_ptr<unsigned char, void (*)(void*)> pixels(
      stbi_load(png.c_str(), &width, &height, &channels, 3), &stbi_image_free);
  ASSERT_TRUE(pixels);
  ASSERT_EQ(width, 101);
  ASSERT_EQ(height, 101);
  const auto at = [&](int x, int y) { return pixels.get()[3 * (y * width + x)]; };
  EXPECT_EQ(at(0, 0), 255);
  EXPECT_EQ(at(100, 100), 255);
  EXPECT_GE(at(50, 50), 225);  // facing the view: 40 + 190 x ~1
  EXPECT_LT(at(50, 50), 255);
  // The box [-1, 1]^3 fills 1 / 1.1 of the picture: the unit disc covers pi / 4 of that square.
  int grey = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) grey += at(x, y) != 255;
  const double square = std::pow(101 / 1.1, 2);
  EXPECT_NEAR(grey / square, M_PI / 4, 0.03);
  EXPECT_GT(stats.boxTests, 0u);
  EXPECT_LT(stats.triangleTests, 101u * 101u * 30u);  // the boxes prune: the sphere has 5,120 triangles
  // The command line writes the same picture.
  const test::CliResult run = test::runCli("render " + fch.string() + " --raycast --width 101 --height 101 " +
                                           "--view 0,0,-1 --up 0,1,0 -o " + cli.string());
  EXPECT_EQ(run.exitCode, 0) << run.out;
  EXPECT_NE(run.out.find("rays a second"), std::string::npos) << run.out;
  EXPECT_EQ(test::runCli("render " + fch.string() + " --raycast --cut 5 -o " + cli.string()).exitCode, 2);
}

}  // namespace
}  // namespace facetree
