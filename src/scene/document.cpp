// Reading a scene: the YAML text loaded into a node tree (one document, bounded in size and
// stoppable), the --set overrides applied to that tree (overrides.cpp), and the tree validated
// into the Scene structs (readers.cpp). Every problem throws InputError with one line
// "<file>:<line>: <dotted.key.path>: <what is wrong>".
#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <sstream>

#include "overrides.hpp"
#include "readers.hpp"
#include "schema.hpp"

namespace peri {

/// The byte offset of the first byte of `text` that is not part of well-formed UTF-8 (overlong
/// forms, surrogates and code points beyond U+10FFFF included), or npos. yaml-cpp reads bytes
/// as they come, and a scene's strings end up in HDF5 datasets declared UTF-8 (the scene text of
/// every frames file and checkpoint), which readers then cannot decode.
std::size_t scene_detail::first_bad_utf8(const std::string& text) {
  const auto* b = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned c = b[i];
    std::size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the second byte's range
    if (c < 0x80) len = 1;
    else if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c == 0xE0) len = 3, lo = 0xA0;
    else if (c == 0xED) len = 3, hi = 0x9F;
    else if (c >= 0xE1 && c <= 0xEF) len = 3;
    else if (c == 0xF0) len = 4, lo = 0x90;
    else if (c == 0xF4) len = 4, hi = 0x8F;
    else if (c >= 0xF1 && c <= 0xF3) len = 4;
    else return i;
    if (i + len > n) return i;
    for (std::size_t k = 1; k < len; ++k) {
      const unsigned d = b[i + k];
      if (d < (k == 1 ? lo : 0x80u) || d > (k == 1 ? hi : 0xBFu)) return i;
    }
    i += len;
  }
  return std::string::npos;
}

namespace {

using namespace scene_detail;

std::string top_level_keys() {
  std::vector<std::string> names;
  for (const Key& k : kSceneKeys) names.emplace_back(k.name);
  return join(names);
}

/// Counts the documents of a YAML stream and where each starts, and the values they hold (at
/// most kMaxSceneValues, else InputError naming the top-level key being read), without building
/// nodes.
class DocumentCounter : public YAML::EventHandler {
 public:
  explicit DocumentCounter(std::string file) : file_(std::move(file)) {}
  std::vector<YAML::Mark> starts;  ///< per document: where it starts
  std::vector<YAML::Mark> roots;   ///< per document: where its root node starts
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t anchor) override {
    value(m, nullptr);
    anchored(anchor, 1);
  }
  // An alias stands for its anchor's node with every value in it: counted as that many, so
  // that aliases of aliases cannot expand a small text into a huge scene.
  void OnAlias(const YAML::Mark& m, YAML::anchor_t anchor) override {
    const auto it = sizes_.find(anchor);
    value(m, nullptr, it == sizes_.end() ? 1 : it->second);
  }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t anchor, const std::string& text) override {
    value(m, &text);
    anchored(anchor, 1);
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t anchor,
                       YAML::EmitterStyle::value) override {
    open_.push_back({anchor, values_});
    value(m, nullptr);
    ++depth_;
  }
  void OnSequenceEnd() override { close(); }
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t anchor, YAML::EmitterStyle::value) override {
    open_.push_back({anchor, values_});
    value(m, nullptr);
    ++depth_;
  }
  void OnMapEnd() override { close(); }

 private:
  void anchored(YAML::anchor_t anchor, long size) {
    if (anchor) sizes_[anchor] = size;
  }
  void close() {
    --depth_;
    anchored(open_.back().first, values_ - open_.back().second);
    open_.pop_back();
  }
  void value(const YAML::Mark& m, const std::string* scalar, long count = 1) {
    if (roots.size() < starts.size()) roots.push_back(m);
    // Directly inside the top-level map, entries alternate key and value.
    if (depth_ == 1) {
      if (key_next_ && scalar) key_ = *scalar;
      key_next_ = !key_next_;
    }
    values_ += count;
    if (values_ <= kMaxSceneValues) return;
    throw InputError(SourceLoc{file_, m.line >= 0 ? m.line + 1 : 1}.str() + ": " + (key_.empty() ? "top level" : key_) +
                     ": the scene holds more than " + std::to_string(kMaxSceneValues) +
                     " YAML values (numbers, strings, lists, maps) by this line; expected at most " +
                     std::to_string(kMaxSceneValues) + " (about 90000 cracks written as {from: [x, y, z], to: [x, y, z]})");
  }

  std::string file_;
  std::string key_;  // top-level key whose value is being read
  int depth_ = 0;
  bool key_next_ = true;
  long values_ = 0;
  std::vector<std::pair<YAML::anchor_t, long>> open_;  // collections being read: anchor, values before
  std::map<YAML::anchor_t, long> sizes_;               // anchored nodes: their values, aliases expanded
};

/// The scene text handed to yaml-cpp in 64 KiB pieces, asking `stop` before each piece (yaml-cpp
/// reads through the stream buffer as it scans), so that a long text can be abandoned mid-way.
class StoppableText : public std::streambuf {
 public:
  StoppableText(const std::string& text, const StopCheck& stop) : text_(text), stop_(stop) {}

 protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    if (next_ >= text_.size()) return traits_type::eof();
    if (stop_ && stop_()) throw StopRequested("stopped while reading the scene");
    char* begin = const_cast<char*>(text_.data()) + next_;
    next_ = std::min(text_.size(), next_ + (std::size_t{1} << 16));
    setg(begin, begin, const_cast<char*>(text_.data()) + next_);
    return traits_type::to_int_type(*begin);
  }

 private:
  const std::string& text_;
  const StopCheck& stop_;
  std::size_t next_ = 0;
};

/// A stream over a StoppableText whose reads let the stop request (StopRequested) reach the caller.
struct StoppableStream : std::istream {
  StoppableStream(const std::string& text, const StopCheck& stop) : std::istream(nullptr), buffer(text, stop) {
    rdbuf(&buffer);
    exceptions(std::ios::badbit);
  }
  StoppableText buffer;
};

YAML::Node load_document(const std::string& text, const std::string& file, const StopCheck& stop) {
  if (const std::size_t bad = first_bad_utf8(text); bad != std::string::npos) {
    const long line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(bad), '\n');
    char byte[8];
    std::snprintf(byte, sizeof byte, "0x%02X", static_cast<unsigned char>(text[bad]));
    throw InputError(SourceLoc{file, static_cast<int>(line)}.str() + ": the byte " + byte + " at offset " + std::to_string(bad) +
                     " is not UTF-8 text" +
                     (text.size() >= 2 && (text.compare(0, 2, "\xFF\xFE") == 0 || text.compare(0, 2, "\xFE\xFF") == 0)
                          ? " (the file starts with a UTF-16 byte order mark: save it as UTF-8)"
                          : "") +
                     "; expected a scene in UTF-8");
  }
  std::vector<YAML::Node> docs;
  try {
    // Count the documents first. YAML::LoadAll is not used: on a token that starts no node (a
    // ',' outside a flow collection) yaml-cpp returns the same empty document forever, filling
    // memory; a document that starts where the previous one started is that token.
    DocumentCounter counter(file);
    StoppableStream in(text, stop);
    YAML::Parser parser(in);
    while (parser.HandleNextDocument(counter)) {
      const std::size_t n = counter.starts.size();
      if (n >= 2 && counter.starts[n - 1].pos == counter.starts[n - 2].pos) {
        const YAML::Mark& m = counter.starts[n - 1];
        throw InputError(SourceLoc{file, m.line >= 0 ? m.line + 1 : 1}.str() +
                         ": YAML syntax error: unexpected character '" +
                         (m.pos >= 0 && static_cast<std::size_t>(m.pos) < text.size() ? text.substr(m.pos, 1) : "") +
                         "' where a value should start");
      }
    }
    if (counter.starts.size() > 1) {
      const YAML::Mark& m = counter.roots.size() > 1 ? counter.roots[1] : counter.starts[1];
      throw InputError(SourceLoc{file, m.line >= 0 ? m.line + 1 : 1}.str() +
                       ": expected a single YAML document, found " + std::to_string(counter.starts.size()));
    }
    if (!counter.starts.empty()) {
      StoppableStream again(text, stop);
      docs.push_back(YAML::Load(again));
    }
  } catch (const YAML::Exception& e) {
    throw InputError(SourceLoc{file, e.mark.line >= 0 ? e.mark.line + 1 : 1}.str() +
                     ": YAML syntax error: " + e.msg);
  }
  if (docs.empty() || docs[0].IsNull()) {
    throw InputError(file + ":1: the scene is empty; expected a YAML map with the keys: " + top_level_keys());
  }
  if (!docs[0].IsMap()) {
    throw InputError(file + ":1: expected a YAML map at the top level (keys: " + top_level_keys() +
                     "), got " + describe(docs[0]));
  }
  return docs[0];
}

}  // namespace

Scene parse_scene(const std::string& text, const std::string& file, const std::vector<Override>& overrides,
                  const StopCheck& stop) {
  Context ctx(file);
  YAML::Node root = load_document(text, file, stop);
  for (const Override& o : overrides) apply_override(root, o, ctx);
  return read_scene(ctx, root, file);
}

Scene load_scene(const std::string& path, const std::vector<Override>& overrides, const StopCheck& stop) {
  const auto fail = [&](int err) {
    throw InputError("cannot read scene file '" + path + "': " + std::strerror(err));
  };
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) fail(errno);
  std::string text;
  char buf[1 << 16];
  for (;;) {
    const std::size_t n = std::fread(buf, 1, sizeof buf, f.get());
    text.append(buf, n);
    if (n < sizeof buf) break;
  }
  if (std::ferror(f.get())) fail(errno != 0 ? errno : EIO);
  return parse_scene(text, path, overrides, stop);
}

}  // namespace peri
