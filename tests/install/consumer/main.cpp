// Builds the hierarchy of an octahedron through the installed library's public API.
#include <facetree.h>

#include <cstdio>
#include <vector>

int main() {
  const std::vector<glm::vec3> positions = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                            {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
  const std::vector<uint32_t> indices = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4,
                                         2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  const facetree::Hierarchy hierarchy = facetree::buildHierarchy({positions, indices});
  std::printf("nodes %zu faces %zu root-count %u\n", hierarchy.nodes.size(), hierarchy.faceOrder.size(),
              hierarchy.nodes.at(0).count);
  return hierarchy.nodes.size() == 7 && hierarchy.nodes[0].count == 8 ? 0 : 1;
}
