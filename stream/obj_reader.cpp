// Wavefront OBJ reader: `v` and `f` statements; everything else is ignored.
//
// OBJ has no header, so the vertex count is not known in advance and vertices may be
// interleaved with faces. Faces are streamed as they are read and refer to the vertices seen
// so far (a face referring to a later vertex is "out of range", as in any valid OBJ), so
// vertices() grows while reading and is complete once read() returned 0.
#include <string>
#include <vector>

#include "read_error.h"
#include "readers.h"
#include "text_tokens.h"
#include "vertex_store.h"

namespace facetree::stream_detail {
namespace {

class ObjReader final : public ReaderBase {
 public:
  ObjReader(std::unique_ptr<InputBuffer> input, MeshInfo info) : input_(std::move(input)) {
    info_ = std::move(info);
    info_.format = MeshFormat::Obj;
  }

 protected:
  // Every face goes through pending_.
  size_t produce(Triangle*, size_t) override {
    std::string_view statement;
    while (pending_.empty() && nextStatement(statement)) parseStatement(statement);
    return 0;
  }

  void finishReading() override {
    if (stats_.faces == 0) fail("no faces");
  }

  uint64_t inputOffset() const override { return input_->offset(); }
  uint64_t compressedOffset() const override { return input_->source().compressedBytesRead(); }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throwReadError(info_.name, Place::line(line_), reason);
  }

  bool nextLine(std::string_view& text) { return input_->readLine(text, line_, info_.name); }

  // One logical line: physical lines ending in '\' are joined (the view then points into
  // joined_). Errors name the last physical line.
  bool nextStatement(std::string_view& statement) {
    if (!nextLine(statement)) return false;
    if (statement.empty() || statement.back() != '\\') return true;
    joined_.assign(statement.substr(0, statement.size() - 1));
    std::string_view more;
    while (nextLine(more)) {
      const bool continues = !more.empty() && more.back() == '\\';
      if (continues) more.remove_suffix(1);
      if (joined_.size() + more.size() + 1 > kMaxLineBytes)
        fail("line longer than " + std::to_string(kMaxLineBytes) + " bytes");
      joined_ += ' ';
      joined_ += more;
      if (!continues) break;
    }
    statement = joined_;
    return true;
  }

  void parseStatement(std::string_view statement) {
    Tokens tokens(statement);
    const std::string_view keyword = tokens.next();
    if (keyword == "v") {
      parseVertex(tokens);
    } else if (keyword == "f") {
      parseFace(tokens);
    }
  }

  void parseVertex(Tokens& tokens) {
    glm::vec3 position;
    for (int axis = 0; axis < 3; ++axis) {
      const std::string_view token = tokens.next();
      if (token.empty() || token[0] == '#') fail("vertex has fewer than 3 coordinates");
      if (!parseNumber(token, position[axis])) fail("invalid number " + quoteToken(token));
    }
    if (vertices_.size() >= kMaxVertices) fail("more than " + std::to_string(kMaxVertices) + " vertices");
    addVertex(position);  // w and vertex colours, if any, are ignored
  }

  uint32_t resolveIndex(std::string_view token) const {
    const std::string_view text = token.substr(0, token.find('/'));
    int64_t value = 0;
    if (!parseNumber(text, value))
      fail("face " + std::to_string(stats_.faces) + ": invalid vertex index " + quoteToken(token));
    const auto count = static_cast<int64_t>(vertices_.size());
    if (value == 0)
      fail("face " + std::to_string(stats_.faces) + ": vertex index 0 is invalid (obj indices start at 1)");
    // Negative indices count back from the last vertex defined so far.
    const int64_t resolved = value > 0 ? value - 1 : count + value;
    if (resolved < 0 || resolved >= count)
      fail("face " + std::to_string(stats_.faces) + ": vertex index " + std::to_string(value) +
           " out of range (" + std::to_string(count) + " vertices)");
    return static_cast<uint32_t>(resolved);
  }

  void parseFace(Tokens& tokens) {
    polygon_.clear();
    for (std::string_view token = tokens.next(); !token.empty() && token[0] != '#'; token = tokens.next())
      polygon_.push_back(resolveIndex(token));
    if (polygon_.size() < 3)
      fail("face " + std::to_string(stats_.faces) + " has " + std::to_string(polygon_.size()) + " vertices");
    pending_.fan(stats_.faces++, polygon_);
  }

  std::unique_ptr<InputBuffer> input_;
  uint64_t line_ = 0;
  std::string joined_;
  std::vector<uint32_t> polygon_;
};

}  // namespace

std::unique_ptr<TriangleReader> makeObjReader(std::unique_ptr<InputBuffer> input, MeshInfo info) {
  return std::make_unique<ObjReader>(std::move(input), std::move(info));
}

}  // namespace facetree::stream_detail
