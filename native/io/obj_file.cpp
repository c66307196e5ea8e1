#include "io/obj_file.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "core/ear_clipping.hpp"
#include "core/geometry.hpp"

namespace atlas::obj {
namespace {

// The whole file in memory: one read, then parsing in place, instead of
// line-by-line streams (bench/README.md).
std::string file_contents(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw FileError("read", path, errno);
  std::string text;
  std::error_code unknown;
  const auto size = std::filesystem::file_size(path, unknown);
  if (!unknown) text.reserve(size);  // one allocation, not a series of doublings and copies
  char buffer[1 << 16];
  for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0;) text.append(buffer, n);
  if (std::ferror(file.get())) throw FileError("read", path, errno);
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

  // The rest of the line ends before a `#`.
  void drop_comment() { rest_ = rest_.substr(0, rest_.find('#')); }

  // Everything after the keyword, without surrounding blanks (names may hold spaces).
  std::string_view remainder() const {
    std::string_view s = rest_;
    while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
    while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
    return s;
  }

  double number() { return number_from(next()); }

  // A number, or NaN where the word is none or missing: for values the
  // reader can do without (a normal), which must not refuse the scan.
  double number_or_nan() {
    return parsed_number(next()).value_or(std::numeric_limits<double>::quiet_NaN());
  }

  // A number that may be left out at the end of the line.
  double number_or(double absent) {
    const std::string_view word = next();
    return word.empty() ? absent : number_from(word);
  }

  [[noreturn]] void fail(const char* expected, std::string_view word) const {
    std::ostringstream msg;
    msg << "OBJ line " << number_ << ": expected " << expected << ", got '" << word << "'";
    throw InputError(msg.str());
  }

  int line_number() const { return number_; }

 private:
  // The number the whole word writes, if it writes one.
  static std::optional<double> parsed_number(std::string_view word) {
    if (!word.empty() && word.front() == '+') word.remove_prefix(1);  // from_chars takes no '+'
    double value = 0;
    const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
    if (word.empty() || error != std::errc() || end != word.data() + word.size()) return std::nullopt;
    return value;
  }

  double number_from(std::string_view word) const {
    const std::optional<double> value = parsed_number(word);
    if (!value) fail("a number", word);
    return *value;
  }

  std::string_view rest_;
  int number_;
};

// One index of a face corner as written (1-based, or negative from the end
// of the elements defined so far) and as a 0-based index, -1 when it names
// none of the `count` elements; a token that is no integer throws.
struct CornerIndex {
  long long written = 0, index = -1;
};
CornerIndex parsed_index(std::string_view token, int count, const Words& words) {
  CornerIndex out;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), out.written);
  if (token.empty() || error != std::errc() || end != token.data() + token.size()) words.fail("an index", token);
  const long long index = out.written > 0 ? out.written - 1 : count + out.written;
  if (out.written != 0 && index >= 0 && index < count) out.index = index;
  return out;
}

// parsed_index's 0-based index; InputError naming the line when it names none.
int element_index(std::string_view token, int count, const char* what, const Words& words) {
  const CornerIndex i = parsed_index(token, count, words);
  if (i.index < 0) {
    std::ostringstream msg;
    msg << "OBJ line " << words.line_number() << ": " << what << " index " << i.written << " is outside the "
        << count << " defined before it";
    throw InputError(msg.str());
  }
  return static_cast<int>(i.index);
}

// What the parser gathers before the arrays are built.
struct Lists {
  std::vector<double> positions, texcoords, normals;
  std::vector<int> corners, corner_texcoords, corner_normals, face_material;
  // Of the face being read, kept to spare an allocation per face.
  std::vector<int> face_vertices, face_texcoords, face_normals;
  std::unordered_map<std::string, int> material_of;
  int material = -1;
  ObjFile out;
};

// The corners of a polygon seen along its Newell normal (the normal of its
// area), so that it turns counter-clockwise; empty when it has no area.
std::vector<Eigen::Vector2d> projected(const std::vector<double>& positions, const std::vector<int>& vertex) {
  auto at = [&](int v) { return Eigen::Vector3d(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]); };
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < vertex.size(); ++i) normal += at(vertex[i]).cross(at(vertex[(i + 1) % vertex.size()]));
  if (!(normal.norm() > 0) || !normal.allFinite()) return {};
  const Eigen::Vector3d u = normal.unitOrthogonal();
  const Eigen::Vector3d v = normal.normalized().cross(u);
  std::vector<Eigen::Vector2d> points;
  for (int k : vertex) points.emplace_back(u.dot(at(k)), v.dot(at(k)));
  return points;
}

// Corner triples of a polygon: a fan when it is convex (every triangle
// inside it), else ear clipping in its plane, where a fan from a reflex
// corner would cover ground outside the polygon and fold its UVs over; a fan
// again when clipping fails (a polygon crossing itself has no right answer).
std::vector<Eigen::Vector3i> polygon_triangles(const std::vector<double>& positions, const std::vector<int>& vertex) {
  const int n = static_cast<int>(vertex.size());
  std::vector<Eigen::Vector3i> triangles;
  const std::vector<Eigen::Vector2d> points = projected(positions, vertex);
  if (!points.empty()) {
    bool convex = true;
    for (int i = 0; i < n && convex; ++i)
      convex = signed_area(points[i], points[(i + 1) % n], points[(i + 2) % n]) >= 0;
    if (!convex) {
      std::vector<int> order(n);
      std::iota(order.begin(), order.end(), 0);
      if (clip_ears(points, order, triangles)) return triangles;
      triangles.clear();
    }
  }
  for (int i = 1; i + 1 < n; ++i) triangles.emplace_back(0, i, i + 1);
  return triangles;
}

// A `f` line: corners v, v/vt, v//vn or v/vt/vn, as triangles (polygon_triangles).
void read_face(Words& words, Lists& lists) {
  std::vector<int>& vertex = lists.face_vertices;
  std::vector<int>& texcoord = lists.face_texcoords;
  std::vector<int>& normal = lists.face_normals;
  vertex.clear(), texcoord.clear(), normal.clear();
  bool textured = true, shaded = true;
  const int vertices = static_cast<int>(lists.positions.size() / 3);
  const int texcoords = static_cast<int>(lists.texcoords.size() / 2);
  const int normals = static_cast<int>(lists.normals.size() / 3);
  for (std::string_view corner = words.next(); !corner.empty(); corner = words.next()) {
    const size_t slash = corner.find('/');
    vertex.push_back(element_index(corner.substr(0, slash), vertices, "vertex", words));
    const std::string_view rest = slash == std::string_view::npos ? std::string_view() : corner.substr(slash + 1);
    const size_t second = rest.find('/');
    const std::string_view uv = rest.substr(0, second);
    const std::string_view n = second == std::string_view::npos ? std::string_view() : rest.substr(second + 1);
    if (uv.empty()) textured = false;
    else texcoord.push_back(element_index(uv, texcoords, "texture coordinate", words));
    // Normals are optional: one the file has not defined before the face
    // (or at all), or one that is no finite vector, leaves the face
    // without, as the writer then leaves it.
    const long long n_index = n.empty() ? -1 : parsed_index(n, normals, words).index;
    const double* row = n_index < 0 ? nullptr : &lists.normals[3 * n_index];
    if (!row || !std::isfinite(row[0]) || !std::isfinite(row[1]) || !std::isfinite(row[2])) shaded = false;
    else normal.push_back(static_cast<int>(n_index));
  }
  auto add = [&](const Eigen::Vector3i& triangle) {
    for (const int k : triangle) {
      lists.corners.push_back(vertex[k]);
      lists.corner_texcoords.push_back(textured ? texcoord[k] : -1);
      lists.corner_normals.push_back(shaded ? normal[k] : -1);
    }
    lists.face_material.push_back(lists.material);
  };
  if (vertex.size() == 3) return add({0, 1, 2});
  for (const Eigen::Vector3i& triangle : polygon_triangles(lists.positions, vertex)) add(triangle);
}

// A name line keeps its `#`s (read_obj's comment); other lines end at the first.
void read_line(std::string_view line, int number, Lists& lists) {
  Words words(line, number);
  const std::string_view keyword = words.next();
  if (keyword != "usemtl" && keyword != "mtllib") words.drop_comment();
  if (keyword == "v") {
    for (int k = 0; k < 3; ++k) lists.positions.push_back(words.number());
    lists.out.vertex_colours |= !words.next().empty() && !words.next().empty();  // x y z r g b, not x y z w
  } else if (keyword == "vn") {  // a malformed one is kept as NaN: the faces naming it get no normals
    for (int k = 0; k < 3; ++k) lists.normals.push_back(words.number_or_nan());
  } else if (keyword == "vt") {
    lists.texcoords.push_back(words.number());
    lists.texcoords.push_back(words.number_or(0.0));
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

// Lines are formatted into a buffer flushed in large blocks.
class TextOut {
 public:
  explicit TextOut(const std::string& path) : file_(std::fopen(path.c_str(), "wb"), &std::fclose), path_(path) {
    if (!file_) throw FileError("write", path, errno);
  }
  TextOut& text(std::string_view s) {
    buffer_.append(s);
    return flush_if_full();
  }
  TextOut& number(double value) {  // %.9g: a float32's digits
    char digits[32];
    const auto end = std::to_chars(digits, digits + sizeof digits, value, std::chars_format::general, 9).ptr;
    buffer_.append(digits, end);
    return *this;
  }
  // The shortest digits that read back as the same number: positions of a
  // scan in map coordinates (UTM northings near 4e6 m) need more than nine.
  // A value a float32 holds (from a GLB) is written as that float, short.
  TextOut& exact(double value) {
    char digits[32];
    const float single = static_cast<float>(value);
    const auto end = static_cast<double>(single) == value
                         ? std::to_chars(digits, digits + sizeof digits, single).ptr
                         : std::to_chars(digits, digits + sizeof digits, value).ptr;
    buffer_.append(digits, end);
    return *this;
  }
  TextOut& integer(long long value) {
    char digits[24];
    buffer_.append(digits, std::to_chars(digits, digits + sizeof digits, value).ptr);
    return *this;
  }
  void close() {
    flush();
    if (std::fclose(file_.release()) != 0) throw FileError("write", path_, errno);
  }

 private:
  TextOut& flush_if_full() {
    if (buffer_.size() > (1 << 20)) flush();
    return *this;
  }
  void flush() {
    if (std::fwrite(buffer_.data(), 1, buffer_.size(), file_.get()) != buffer_.size())
      throw FileError("write", path_, errno);
    buffer_.clear();
  }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file_;
  std::string path_, buffer_;
};

template <class Matrix, class T>
Matrix rows_of(const std::vector<T>& values) {
  return Eigen::Map<const Matrix>(values.data(), static_cast<Eigen::Index>(values.size() / Matrix::ColsAtCompileTime),
                                  Matrix::ColsAtCompileTime);
}

// The lines of a file, each without its end: \n, \r\n or \r (old Mac
// tools), whichever each line has.
class Lines {
 public:
  explicit Lines(std::string_view all) : all_(all), newline_(std::min(all.find('\n'), all.size())) {}
  bool done() const { return start_ >= all_.size(); }

  std::string_view next() {
    if (newline_ < start_) newline_ = std::min(all_.find('\n', start_), all_.size());
    const size_t cr = all_.substr(start_, newline_ - start_).find('\r');
    const size_t end = cr == std::string_view::npos ? newline_ : start_ + cr;
    const std::string_view line = all_.substr(start_, end - start_);
    start_ = end + (end + 1 == newline_ ? 2 : 1);  // past \r\n at once
    return line;
  }

 private:
  std::string_view all_;
  size_t newline_, start_ = 0;
};

// Without the backslash that continues a line in the next (its last
// non-blank character); empty if the line has none.
std::optional<std::string_view> before_backslash(std::string_view line) {
  while (!line.empty() && is_space(line.back())) line.remove_suffix(1);
  if (line.empty() || line.back() != '\\') return std::nullopt;
  return line.substr(0, line.size() - 1);
}

// The next line with the lines it continues into joined to it (in `joined`);
// `number` counts the lines taken.
std::string_view logical_line(Lines& lines, int& number, std::string& joined) {
  std::string_view line = lines.next();
  ++number;
  std::optional<std::string_view> head = before_backslash(line);
  if (!head) return line;
  joined.clear();
  for (; head; head = before_backslash(line)) {
    joined.append(*head) += ' ';
    if (lines.done()) return joined;
    line = lines.next();
    ++number;
  }
  return joined.append(line);
}

// Encodings that read as text without a face: named, so that the user
// knows what to convert instead of being told the mesh is empty.
void refuse_binary_text(std::string_view all, const std::string& path) {
  if (all.substr(0, 2) == "\xFF\xFE" || all.substr(0, 2) == "\xFE\xFF")
    throw InputError(path + " is UTF-16 text: save it as UTF-8 or ASCII");
  if (all.substr(0, 2) == "\x1F\x8B") throw InputError(path + " is gzip-compressed: decompress it first");
}

}  // namespace

ObjFile read_obj(const std::string& path) {
  const std::string text = file_contents(path);
  Lists lists;
  const std::string_view all(text);
  refuse_binary_text(all, path);
  Lines lines(all.substr(all.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0));  // a UTF-8 byte-order mark skipped
  std::string joined;
  for (int taken = 0; !lines.done();) {
    const int number = taken + 1;
    read_line(logical_line(lines, taken, joined), number, lists);
  }
  ObjFile& out = lists.out;
  out.positions = rows_of<RowMatrixX3d>(lists.positions);
  out.texcoords = rows_of<RowMatrixX2d>(lists.texcoords);
  out.triangles = rows_of<RowMatrixX3i>(lists.corners);
  out.texcoord_index = rows_of<RowMatrixX3i>(lists.corner_texcoords);
  out.normals = rows_of<RowMatrixX3d>(lists.normals);
  out.normal_index = rows_of<RowMatrixX3i>(lists.corner_normals);
  out.face_material = Eigen::Map<const Eigen::VectorXi>(lists.face_material.data(),
                                                        static_cast<Eigen::Index>(lists.face_material.size()));
  return std::move(out);
}

void write_obj(const std::string& path, const std::string& library, const RowMatrixX3d& positions,
               const RowMatrixX3i& triangles, const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_material,
               const std::vector<std::string>& materials, const CornerNormals& normals) {
  if (corner_uv.rows() != 3 * triangles.rows() || face_material.size() != triangles.rows())
    throw InputError("write_obj: corner_uv must hold 3 rows and face_material 1 entry per face");
  if (triangles.size() && (triangles.minCoeff() < 0 || triangles.maxCoeff() >= positions.rows()))
    throw InputError("write_obj: triangles refer to vertices that do not exist");
  const RowMatrixX3i& normal = normals.normal_index;
  const bool shaded = normal.rows() > 0;
  if (shaded && normal.rows() != triangles.rows())
    throw InputError("write_obj: normal_index must hold one row per face");
  if (shaded && (normal.minCoeff() < -1 || normal.maxCoeff() >= normals.normals.rows()))
    throw InputError("write_obj: normal_index refers to normals that do not exist");
  std::vector<std::vector<int>> faces_of(materials.size());
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    if (face_material[f] < 0 || face_material[f] >= static_cast<int>(materials.size()))
      throw InputError("write_obj: face_material refers to a material that is not named");
    faces_of[face_material[f]].push_back(static_cast<int>(f));
  }
  TextOut out(path);
  out.text("mtllib ").text(library).text("\n");
  for (Eigen::Index v = 0; v < positions.rows(); ++v)
    out.text("v ").exact(positions(v, 0)).text(" ").exact(positions(v, 1)).text(" ").exact(positions(v, 2)).text("\n");
  for (Eigen::Index c = 0; c < corner_uv.rows(); ++c)
    out.text("vt ").number(corner_uv(c, 0)).text(" ").number(corner_uv(c, 1)).text("\n");
  for (Eigen::Index n = 0; shaded && n < normals.normals.rows(); ++n) {
    const auto row = normals.normals.row(n);
    out.text("vn ").exact(row(0)).text(" ").exact(row(1)).text(" ").exact(row(2)).text("\n");
  }
  for (size_t m = 0; m < materials.size(); ++m) {
    if (faces_of[m].empty()) continue;
    out.text("usemtl ").text(materials[m]).text("\n");
    for (const int f : faces_of[m]) {
      out.text("f");
      const bool with_normals = shaded && normal.row(f).minCoeff() >= 0;
      for (int k = 0; k < 3; ++k) {  // 1-based; corner k of face f is texcoord 3f + k
        out.text(" ").integer(triangles(f, k) + 1).text("/").integer(3LL * f + k + 1);
        if (with_normals) out.text("/").integer(normal(f, k) + 1);
      }
      out.text("\n");
    }
  }
  out.close();
}

}  // namespace atlas::obj
