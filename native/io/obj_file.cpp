#include "io/obj_file.hpp"

#include <charconv>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string_view>
#include <unordered_map>

namespace atlas::obj {
namespace {

// The whole file in memory: a 1M-face scan is about 100 MB of text, and one
// read is several times faster than line-by-line streams.
std::string file_contents(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw InputError("cannot open " + path);
  std::string text;
  char buffer[1 << 16];
  for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0;) text.append(buffer, n);
  if (std::ferror(file.get())) throw InputError("cannot read " + path);
  return text;
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// The whitespace-separated words of one line, read front to back.
class Words {
 public:
  Words(std::string_view line, int number) : rest_(line), number_(number) {}

  // The next word, empty at the end of the line.
  std::string_view next() {
    size_t start = 0;
    while (start < rest_.size() && is_space(rest_[start])) ++start;
    size_t end = start;
    while (end < rest_.size() && !is_space(rest_[end])) ++end;
    const std::string_view word = rest_.substr(start, end - start);
    rest_.remove_prefix(end);
    return word;
  }

  // Everything after the keyword, without surrounding blanks (names may hold spaces).
  std::string_view remainder() const {
    std::string_view s = rest_;
    while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
    while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
    return s;
  }

  double number() {
    std::string_view word = next();
    if (!word.empty() && word.front() == '+') word.remove_prefix(1);  // from_chars takes no '+'
    double value = 0;
    const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
    if (word.empty() || error != std::errc() || end != word.data() + word.size()) fail("a number", word);
    return value;
  }

  [[noreturn]] void fail(const char* expected, std::string_view word) const {
    std::ostringstream msg;
    msg << "OBJ line " << number_ << ": expected " << expected << ", got '" << word << "'";
    throw InputError(msg.str());
  }

  int line_number() const { return number_; }

 private:
  std::string_view rest_;
  int number_;
};

// One index of a face corner (1-based, or negative from the end of the
// elements defined so far) as a 0-based index; `count` elements exist.
int element_index(std::string_view token, int count, const char* what, const Words& words) {
  long long value = 0;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (token.empty() || error != std::errc() || end != token.data() + token.size()) words.fail("an index", token);
  const long long index = value > 0 ? value - 1 : count + value;
  if (value == 0 || index < 0 || index >= count) {
    std::ostringstream msg;
    msg << "OBJ line " << words.line_number() << ": " << what << " index " << value << " is outside the "
        << count << " defined before it";
    throw InputError(msg.str());
  }
  return static_cast<int>(index);
}

// What the parser gathers before the arrays are built.
struct Lists {
  std::vector<double> positions, texcoords;
  std::vector<int> corners, corner_texcoords, face_material;
  std::vector<int> face_vertices, face_texcoords;  // of the face being read, kept to spare an allocation per face
  std::unordered_map<std::string, int> material_of;
  int material = -1;
  ObjFile out;
};

// A `f` line: corners v, v/vt, v//vn or v/vt/vn, as a fan of triangles.
void read_face(Words& words, Lists& lists) {
  std::vector<int>& vertex = lists.face_vertices;
  std::vector<int>& texcoord = lists.face_texcoords;
  vertex.clear(), texcoord.clear();
  bool textured = true;
  const int vertices = static_cast<int>(lists.positions.size() / 3);
  const int texcoords = static_cast<int>(lists.texcoords.size() / 2);
  for (std::string_view corner = words.next(); !corner.empty(); corner = words.next()) {
    const size_t slash = corner.find('/');
    vertex.push_back(element_index(corner.substr(0, slash), vertices, "vertex", words));
    std::string_view uv = slash == std::string_view::npos ? std::string_view() : corner.substr(slash + 1);
    uv = uv.substr(0, uv.find('/'));
    if (uv.empty()) textured = false;
    else texcoord.push_back(element_index(uv, texcoords, "texture coordinate", words));
  }
  for (size_t i = 1; i + 1 < vertex.size(); ++i) {
    for (const size_t k : {size_t(0), i, i + 1}) {
      lists.corners.push_back(vertex[k]);
      lists.corner_texcoords.push_back(textured ? texcoord[k] : -1);
    }
    lists.face_material.push_back(lists.material);
  }
}

void read_line(std::string_view line, int number, Lists& lists) {
  Words words(line, number);
  const std::string_view keyword = words.next();
  if (keyword == "v") {
    for (int k = 0; k < 3; ++k) lists.positions.push_back(words.number());
  } else if (keyword == "vt") {
    for (int k = 0; k < 2; ++k) lists.texcoords.push_back(words.number());
  } else if (keyword == "f") {
    read_face(words, lists);
  } else if (keyword == "usemtl") {
    const std::string name(words.remainder());
    const auto [it, added] = lists.material_of.emplace(name, static_cast<int>(lists.out.materials.size()));
    if (added) lists.out.materials.push_back(name);
    lists.material = it->second;
  } else if (keyword == "mtllib") {
    lists.out.material_libraries.emplace_back(words.remainder());
  }
}

template <class Matrix, class T>
Matrix rows_of(const std::vector<T>& values) {
  return Eigen::Map<const Matrix>(values.data(), static_cast<Eigen::Index>(values.size() / Matrix::ColsAtCompileTime),
                                  Matrix::ColsAtCompileTime);
}

}  // namespace

ObjFile read_obj(const std::string& path) {
  const std::string text = file_contents(path);
  Lists lists;
  const std::string_view all(text);
  int number = 1;
  for (size_t start = 0; start < all.size(); ++number) {
    size_t end = all.find('\n', start);
    if (end == std::string_view::npos) end = all.size();
    std::string_view line = all.substr(start, end - start);
    line = line.substr(0, line.find('#'));
    read_line(line, number, lists);
    start = end + 1;
  }
  ObjFile& out = lists.out;
  out.positions = rows_of<RowMatrixX3d>(lists.positions);
  out.texcoords = rows_of<RowMatrixX2d>(lists.texcoords);
  out.triangles = rows_of<RowMatrixX3i>(lists.corners);
  out.texcoord_index = rows_of<RowMatrixX3i>(lists.corner_texcoords);
  out.face_material = Eigen::Map<const Eigen::VectorXi>(lists.face_material.data(),
                                                        static_cast<Eigen::Index>(lists.face_material.size()));
  return std::move(out);
}

}  // namespace atlas::obj
