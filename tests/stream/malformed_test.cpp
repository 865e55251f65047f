// The malformed corpus (tests/data/malformed, written by make_corpus.py): every file gives
// exactly one Error (Input) whose message is "PATH: PLACE: REASON" with the path as given.
#include <gtest/gtest.h>

#include <set>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

struct Case {
  const char* file;
  const char* message;  // PLACE: REASON
};

// clang-format off
constexpr Case kCases[] = {
    {"draco_garbage.drc", "byte 0: draco decoding failed: input is not a mesh."},
    {"empty.ply", "byte 0: empty file"},
    {"obj_bad_index.obj", "line 5: face 0: invalid vertex index 'x/2'"},
    {"obj_bad_number.obj", "line 2: invalid number '1,5'"},
    {"obj_face_two_vertices.obj", "line 5: face 0 has 2 vertices"},
    {"obj_index_out_of_range.obj", "line 5: face 0: vertex index 5 out of range (4 vertices)"},
    {"obj_index_zero.obj", "line 6: face 1: vertex index 0 is invalid (obj indices start at 1)"},
    {"obj_line_too_long.obj.zst", "line 5: line longer than 1048576 bytes"},
    {"obj_negative_index_out_of_range.obj", "line 6: face 1: vertex index -5 out of range (4 vertices)"},
    {"obj_no_faces.obj", "line 5: no faces"},
    {"obj_vertex_two_coordinates.obj", "line 2: vertex has fewer than 3 coordinates"},
    {"ply_ascii_bad_number.ply", "line 12: invalid number 'one' in vertex 2"},
    {"ply_ascii_extra_value.ply", "line 14: unexpected value '3' after face 0"},
    {"ply_ascii_too_few_indices.ply", "line 14: too few values in face 0"},
    {"ply_ascii_truncated_face.ply", "line 16: unexpected end of data in face 2 of 3"},
    {"ply_binary_header_line_too_long.ply.zst", "line 2: header line longer than 1048576 bytes"},
    {"ply_count_size_overflow.ply", "line 3: header declares 1000000000000000000 vertices of at least 24 bytes: size overflows 64 bits"},
    {"ply_face_two_vertices.ply", "byte 230: face 1 has 2 vertices"},
    {"ply_face_without_vertex_indices.ply", "line 7: face element has no vertex_indices property"},
    {"ply_face_zero_vertices.ply", "line 15: face 1 has 0 vertices"},
    {"ply_header_counts_exceed_data.ply", "line 3: header declares 100 vertices but only 32 bytes remain"},
    {"ply_huge_face_count.ply", "line 7: header declares 1000000000000000 faces but only 61 bytes remain"},
    {"ply_huge_face_count.ply.zst", "byte 245: unexpected end of data in face 1 of 1000000000000000"},
    {"ply_huge_vertex_count.ply", "line 3: header declares 1000000000000000000 vertices but only 61 bytes remain"},
    {"ply_huge_vertex_count.ply.zst", "line 3: header declares 1000000000000000000 vertices, more than 4294967295"},
    {"ply_index_out_of_range.ply", "byte 230: face 1: vertex index 4 out of range (4 vertices)"},
    {"ply_invalid_element_count.ply", "line 3: invalid element count '-4'"},
    {"ply_missing_end_header.ply", "line 9: unexpected end of file in header (missing end_header)"},
    {"ply_missing_format.ply", "line 8: missing format line"},
    {"ply_negative_extra_list_length.ply", "byte 258: face 0: negative list length -3 for property 'uv'"},
    {"ply_negative_index.ply", "line 14: face 0: negative vertex index -1"},
    {"ply_negative_list_count.ply", "byte 216: face 0 has negative vertex count -1"},
    {"ply_no_face_element.ply", "line 7: no face element"},
    {"ply_no_vertex_element.ply", "line 5: no vertex element"},
    {"ply_only_magic.ply", "line 2: unexpected end of file in header (missing end_header)"},
    {"ply_property_before_element.ply", "line 3: property before any element"},
    {"ply_strip_bad_index.ply", "line 14: strip 0: negative vertex index -2"},
    {"ply_trailing_data.ply", "byte 230: unexpected data after the last element"},
    {"ply_truncated_face.ply", "byte 244: unexpected end of data in face 1 of 2"},
    {"ply_truncated_vertex.ply", "line 3: header declares 4 vertices but only 30 bytes remain"},
    {"ply_truncated_vertex.ply.zst", "byte 199: unexpected end of data in vertex 2 of 4"},
    {"ply_unknown_format.ply", "line 2: unknown ply format 'binary_middle_endian'"},
    {"ply_unknown_keyword.ply", "line 3: unknown header keyword 'elemnet'"},
    {"ply_unknown_property_type.ply", "line 4: unknown property type 'float128'"},
    {"ply_vertex_indices_float.ply", "line 7: face property 'vertex_indices' has non-integer type float"},
    {"ply_vertex_indices_not_list.ply", "line 7: face property 'vertex_indices' is not a list"},
    {"ply_vertex_missing_z.ply", "line 3: vertex element has no property 'z'"},
    {"ply_zero_faces.ply", "line 9: no faces"},
    {"stl_ascii_bad_number.stl", "line 4: invalid number 'zero' in facet 0"},
    {"stl_ascii_four_vertices.stl", "line 7: facet 0 has more than 3 vertices"},
    {"stl_ascii_missing_endsolid.stl", "line 8: unexpected end of data (missing endsolid)"},
    {"stl_ascii_no_facets.stl", "line 2: no faces"},
    {"stl_ascii_truncated.stl", "line 11: unexpected end of data in facet 1"},
    {"stl_ascii_unexpected_keyword.stl", "line 10: expected 'outer', found 'inner' in facet 1"},
    {"stl_binary_count_mismatch.stl", "byte 80: binary stl declares 3 triangles (234 bytes) but the file has 184 bytes"},
    {"stl_binary_zero_triangles.stl", "byte 80: no faces"},
    {"unknown_format.bin", "byte 0: unknown mesh format"},
    {"unknown_text.txt", "byte 0: unknown mesh format"},
    {"zstd_corrupt.ply.zst", "byte 0: zstd: data corruption detected"},
    {"zstd_empty.zst", "byte 0: empty file"},
    {"zstd_garbage_after_frame.ply.zst", "byte 186: unexpected data after zstd frame (compressed byte 120)"},
    {"zstd_truncated.ply.zst", "byte 0: truncated zstd stream"},
};
// clang-format on

std::filesystem::path corpus() {
  return std::filesystem::path(FACETREE_TEST_DATA) / "malformed";
}

class StreamMalformed : public ::testing::TestWithParam<Case> {};

TEST_P(StreamMalformed, GivesExactlyOneClearError) {
  const std::filesystem::path path = corpus() / GetParam().file;
  ASSERT_TRUE(std::filesystem::exists(path)) << path;
  // The error may come from openMesh (header) or from read (data): read everything.
  const std::string expected = path.string() + ": " + GetParam().message;
  std::unique_ptr<TriangleReader> reader;
  const std::string message = test::errorOf([&] {
    reader = openMesh(path);
    test::readAll(*reader, 3);
  });
  EXPECT_EQ(message, expected);
  if (reader) {
    // A failed reader keeps failing with the same message.
    std::vector<Triangle> batch(3);
    EXPECT_EQ(test::errorOf([&] { reader->read(batch); }), expected);
  }
}

INSTANTIATE_TEST_SUITE_P(StreamCorpus, StreamMalformed, ::testing::ValuesIn(kCases), [](const auto& info) {
  std::string name = info.param.file;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
});

TEST(StreamMalformedCorpus, EveryFileHasAnExpectedMessage) {
  std::set<std::string> listed;
  for (const Case& c : kCases) listed.insert(c.file);
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(corpus())) {
    if (entry.path().extension() == ".py") continue;
    ++files;
    EXPECT_TRUE(listed.count(entry.path().filename().string())) << entry.path() << " is not in the table";
    EXPECT_LT(entry.file_size(), 100u * 1024u) << entry.path();
  }
  EXPECT_EQ(files, listed.size());
}

TEST(StreamMalformedCorpus, BadInputIsNeverFatalWithEveryBufferSize) {
  // Tiny buffers move every record across refills; the message must not change.
  for (const Case& c : kCases) {
    const std::filesystem::path path = corpus() / c.file;
    for (const size_t buffer : {1, 7, 64}) {
      const std::string message = test::errorOf([&] {
        auto reader = openMesh(path, {.bufferBytes = buffer});
        test::readAll(*reader, 2);
      });
      EXPECT_EQ(message, path.string() + ": " + c.message) << "buffer " << buffer;
    }
  }
}

}  // namespace
}  // namespace facetree
