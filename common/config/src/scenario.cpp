// Scenario files: parsing with yaml-cpp, validation that collects every
// problem with its file:line:column and dotted field path, and the derived
// quantities (initial states, services). The schema is config/swarms/SCHEMA.md.
#include "artms/config/scenario.hpp"

#include "artms/dynamics/j2_mean.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iomanip>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string_view>
#include <utility>

#include "artms/astro/constants.hpp"
#include "artms/astro/roe.hpp"
#include "artms/io/duration.hpp"

namespace artms::config {

// ---------------------------------------------------------------------------
// Diagnostic / ScenarioError

std::string Diagnostic::format() const {
  std::string out = file;
  if (line > 0) {
    out += ':' + std::to_string(line) + ':' + std::to_string(column);
  }
  if (!field.empty()) out += ": " + field;
  out += ": " + message;
  return out;
}

namespace {

std::string join_diagnostics(const std::vector<Diagnostic>& diagnostics) {
  std::string out;
  for (std::size_t k = 0; k < diagnostics.size(); ++k) {
    if (k > 0) out += '\n';
    out += diagnostics[k].format();
  }
  return out;
}

}  // namespace

ScenarioError::ScenarioError(std::vector<Diagnostic> diagnostics)
    : std::runtime_error(join_diagnostics(diagnostics)), diagnostics_(std::move(diagnostics)) {}

namespace {

// Lowest perigee altitude accepted for any initial orbit.
constexpr double kMinAltitude_m = 100e3;
constexpr double kMinRadius_m = astro::kRadiusEarth_m + kMinAltitude_m;
// Shipped gravity field (data/gravity/GGM01S.gfc) is complete to this degree.
constexpr int kMaxGravityDegree = 120;

// ---------------------------------------------------------------------------
// Locations, values and the diagnostics sink

struct Loc {
  int line = 0;    // 1-based, 0 = unknown
  int column = 0;  // 1-based
};

Loc loc_of(const YAML::Node& n) {
  if (!n.IsDefined()) return {};
  const YAML::Mark m = n.Mark();
  if (m.is_null()) return {};
  return {m.line + 1, m.column + 1};
}

// A value in the document with where it is and its dotted path.
struct Val {
  YAML::Node node;
  Loc loc;  // the value's position (the key's when the value is null)
  std::string path;
};

std::string fmt_num(double v) {
  std::ostringstream os;
  os << std::setprecision(12) << v;
  return os.str();
}

std::string quote(std::string_view s) {
  return "'" + std::string(s) + "'";
}

// What a node is, for "expected X, got Y".
std::string describe(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined:
      return "nothing (null)";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Scalar:
      break;
  }
  if (n.Tag() == "!") return "the string \"" + n.Scalar() + "\"";
  return quote(n.Scalar());
}

class Ctx {
 public:
  explicit Ctx(std::string file) : file_(std::move(file)) {}
  void error(Loc loc, std::string field, std::string message) {
    diags_.push_back({file_, loc.line, loc.column, std::move(field), std::move(message)});
  }
  void error(const Val& v, std::string message) { error(v.loc, v.path, std::move(message)); }
  [[nodiscard]] std::size_t count() const { return diags_.size(); }
  std::vector<Diagnostic> take() {
    std::stable_sort(diags_.begin(), diags_.end(), [](const Diagnostic& a, const Diagnostic& b) {
      return std::pair(a.line, a.column) < std::pair(b.line, b.column);
    });
    return std::move(diags_);
  }

 private:
  std::string file_;
  std::vector<Diagnostic> diags_;
};

// Levenshtein distance, for "did you mean" on unknown keys.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// A mapping with a fixed set of allowed keys. Construction reports a value
// that is not a mapping, unknown keys (at every level) and duplicate keys.
class Map {
 public:
  Map(Ctx& ctx, const Val& v, std::vector<std::string_view> allowed)
      : ctx_(ctx), self_(v), allowed_(std::move(allowed)) {
    if (!v.node.IsMap()) {
      ctx_.error(v, "expected a mapping with keys " + allowed_list() + ", got " + describe(v.node));
      return;
    }
    ok_ = true;
    for (auto it = v.node.begin(); it != v.node.end(); ++it) {
      const YAML::Node key = it->first;
      const Loc key_loc = loc_of(key);
      if (!key.IsScalar()) {
        ctx_.error(key_loc, v.path, "keys must be plain names, got " + describe(key));
        continue;
      }
      const std::string& name = key.Scalar();
      const std::string kpath = child_path(name);
      if (std::find(allowed_.begin(), allowed_.end(), name) == allowed_.end()) {
        std::string msg = "unknown key " + quote(name);
        std::string_view best;
        std::size_t best_d = std::numeric_limits<std::size_t>::max();
        for (const auto a : allowed_) {
          const std::size_t d = edit_distance(name, a);
          if (d < best_d) {
            best_d = d;
            best = a;
          }
        }
        if (best_d <= 2 || (best_d <= 3 && name.size() > 6)) {
          msg += " (did you mean " + quote(best) + "?)";
        }
        msg += "; allowed keys here: " + allowed_list();
        ctx_.error(key_loc, kpath, msg);
        continue;
      }
      if (entries_.count(name) != 0) {
        ctx_.error(key_loc, kpath,
                   "duplicate key " + quote(name) + " (first given at line " +
                       std::to_string(entries_.at(name).key_loc.line) + ")");
        continue;
      }
      const YAML::Node value = it->second;
      Loc vloc = loc_of(value);
      if (value.IsNull() || vloc.line == 0) vloc = key_loc;
      entries_.emplace(name, Entry{Val{value, vloc, kpath}, key_loc});
    }
  }

  [[nodiscard]] bool ok() const { return ok_; }
  [[nodiscard]] bool has(std::string_view key) const {
    return entries_.count(std::string(key)) != 0;
  }
  [[nodiscard]] const Val* find(std::string_view key) const {
    const auto it = entries_.find(std::string(key));
    return it == entries_.end() ? nullptr : &it->second.val;
  }
  // Reports a missing required key (at the mapping) and returns nullptr.
  const Val* require(std::string_view key, std::string_view expected) {
    if (!ok_) return nullptr;
    const Val* v = find(key);
    if (v == nullptr) {
      ctx_.error(
          self_.loc, child_path(key),
          "missing required field " + quote(key) + " (expected " + std::string(expected) + ")");
    }
    return v;
  }
  [[nodiscard]] Loc key_loc(std::string_view key) const {
    const auto it = entries_.find(std::string(key));
    return it == entries_.end() ? self_.loc : it->second.key_loc;
  }
  [[nodiscard]] std::string child_path(std::string_view key) const {
    return self_.path.empty() ? std::string(key) : self_.path + "." + std::string(key);
  }
  [[nodiscard]] const Val& self() const { return self_; }

 private:
  struct Entry {
    Val val;
    Loc key_loc;
  };
  [[nodiscard]] std::string allowed_list() const {
    std::string s;
    for (std::size_t k = 0; k < allowed_.size(); ++k) {
      if (k > 0) s += ", ";
      s += allowed_[k];
    }
    return s;
  }
  Ctx& ctx_;
  Val self_;
  std::vector<std::string_view> allowed_;
  std::map<std::string, Entry> entries_;
  bool ok_ = false;
};

// Elements of a list; reports a value that is not a list.
std::optional<std::vector<Val>> items(Ctx& ctx, const Val& v, std::string_view what) {
  if (!v.node.IsSequence()) {
    ctx.error(v, "expected a list of " + std::string(what) + ", got " + describe(v.node));
    return std::nullopt;
  }
  std::vector<Val> out;
  for (std::size_t k = 0; k < v.node.size(); ++k) {
    const YAML::Node n = v.node[k];
    Loc loc = loc_of(n);
    if (n.IsNull() || loc.line == 0) loc = v.loc;
    out.push_back({n, loc, v.path + "[" + std::to_string(k) + "]"});
  }
  return out;
}

// ---------------------------------------------------------------------------
// Scalars

bool is_plain_scalar(const YAML::Node& n) {
  return n.IsScalar() && n.Tag() != "!";
}

std::optional<std::string> read_string(Ctx& ctx, const Val& v, std::string_view expected) {
  if (!v.node.IsScalar()) {
    ctx.error(v, "expected " + std::string(expected) + ", got " + describe(v.node));
    return std::nullopt;
  }
  return v.node.Scalar();
}

// A value that is one of a few names: out takes the matching one; any other
// value is reported as "expected <expected>, got ...".
template <typename E>
void choice(Ctx& ctx, const Val& v, std::string_view expected,
            std::initializer_list<std::pair<std::string_view, E>> names, E& out) {
  const auto s = read_string(ctx, v, expected);
  if (!s) return;
  for (const auto& [name, value] : names) {
    if (*s == name) {
      out = value;
      return;
    }
  }
  ctx.error(v, "expected " + std::string(expected) + ", got " + describe(v.node));
}

// Spacecraft ids: at most 20 characters (see the id check below).
constexpr std::size_t kMaxSpacecraftIdChars = 20;

// A string matching [A-Za-z0-9_-]+ (spacecraft ids, camera model stems).
bool is_identifier(std::string_view s, bool allow_dot = false) {
  if (s.empty()) return false;
  return std::all_of(s.begin(), s.end(), [&](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || (allow_dot && c == '.');
  });
}

std::optional<std::string> read_identifier(Ctx& ctx, const Val& v, std::string_view what,
                                           bool allow_dot = false) {
  const auto s = read_string(ctx, v, what);
  if (!s) return std::nullopt;
  if (!is_identifier(*s, allow_dot)) {
    ctx.error(v, "expected " + std::string(what) + " made of letters, digits, '_'" +
                     (allow_dot ? ", '-' and '.'" : " and '-'") + ", got " + quote(*s));
    return std::nullopt;
  }
  return s;
}

// Parses the whole of `text` as a double (YAML's .inf/.nan spellings included
// so that they can be reported as non-finite).
std::optional<double> parse_double(std::string_view text) {
  std::string_view t = text;
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  static const std::map<std::string, double, std::less<>> special = {
      {".inf", std::numeric_limits<double>::infinity()},
      {".Inf", std::numeric_limits<double>::infinity()},
      {".INF", std::numeric_limits<double>::infinity()},
      {"-.inf", -std::numeric_limits<double>::infinity()},
      {"-.Inf", -std::numeric_limits<double>::infinity()},
      {"-.INF", -std::numeric_limits<double>::infinity()},
      {".nan", std::numeric_limits<double>::quiet_NaN()},
      {".NaN", std::numeric_limits<double>::quiet_NaN()},
      {".NAN", std::numeric_limits<double>::quiet_NaN()}};
  if (const auto it = special.find(t); it != special.end()) return it->second;
  double value = 0.0;
  const auto res = std::from_chars(t.data(), t.data() + t.size(), value);
  if (t.empty() || res.ptr != t.data() + t.size()) return std::nullopt;
  if (res.ec == std::errc::result_out_of_range) {
    // Overflow (1e400) is not finite; underflow (1e-400) is as good as zero.
    const auto e = t.find_first_of("eE");
    const bool underflow = e != std::string_view::npos && e + 1 < t.size() && t[e + 1] == '-';
    if (underflow) return 0.0;
    return t.front() == '-' ? -std::numeric_limits<double>::infinity()
                            : std::numeric_limits<double>::infinity();
  }
  if (res.ec != std::errc{}) return std::nullopt;
  return value;
}

std::optional<double> read_number(Ctx& ctx, const Val& v) {
  if (!is_plain_scalar(v.node)) {
    ctx.error(v, "expected a number, got " + describe(v.node));
    return std::nullopt;
  }
  const auto x = parse_double(v.node.Scalar());
  if (!x) {
    ctx.error(v, "expected a number, got " + describe(v.node));
    return std::nullopt;
  }
  if (!std::isfinite(*x)) {
    ctx.error(v, "expected a finite number, got " + describe(v.node));
    return std::nullopt;
  }
  return x;
}

std::optional<std::int64_t> read_integer(Ctx& ctx, const Val& v) {
  if (!is_plain_scalar(v.node)) {
    ctx.error(v, "expected an integer, got " + describe(v.node));
    return std::nullopt;
  }
  std::string_view t = v.node.Scalar();
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  std::int64_t value = 0;
  const auto res = std::from_chars(t.data(), t.data() + t.size(), value);
  if (t.empty() || res.ec != std::errc{} || res.ptr != t.data() + t.size()) {
    ctx.error(v, "expected an integer, got " + describe(v.node));
    return std::nullopt;
  }
  return value;
}

std::optional<bool> read_bool(Ctx& ctx, const Val& v) {
  if (is_plain_scalar(v.node)) {
    const std::string& s = v.node.Scalar();
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
  }
  ctx.error(v, "expected true or false, got " + describe(v.node));
  return std::nullopt;
}

// Allowed interval of a number; expectation text like "0 <= e < 1".
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  std::string note = {};  // appended in parentheses

  [[nodiscard]] bool contains(double x) const {
    const bool lo_ok = lo_open ? x > lo : x >= lo;
    const bool hi_ok = hi_open ? x < hi : x <= hi;
    return lo_ok && hi_ok;
  }
  // "0 <= e < 1", "a_km >= 6478.1363 km (Earth radius + 100 km)".
  [[nodiscard]] std::string text(std::string_view name, std::string_view unit) const {
    const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
    const std::string u = unit.empty() ? std::string() : " " + std::string(unit);
    std::string s;
    if (has_lo && has_hi) {
      s = fmt_num(lo) + (lo_open ? " < " : " <= ") + std::string(name) +
          (hi_open ? " < " : " <= ") + fmt_num(hi) + u;
    } else if (has_lo) {
      s = std::string(name) + (lo_open ? " > " : " >= ") + fmt_num(lo) + u;
    } else if (has_hi) {
      s = std::string(name) + (hi_open ? " < " : " <= ") + fmt_num(hi) + u;
    } else {
      s = std::string(name) + " finite";
    }
    if (!note.empty()) s += " (" + note + ")";
    return s;
  }
};

constexpr double kInf = std::numeric_limits<double>::infinity();
Range positive(std::string note = {}) {
  return {0.0, kInf, true, false, std::move(note)};
}
Range non_negative(std::string note = {}) {
  return {0.0, kInf, false, false, std::move(note)};
}
Range closed(double lo, double hi, std::string note = {}) {
  return {lo, hi, false, false, std::move(note)};
}
Range any_finite() {
  return {};
}

// The last component of a dotted path, as the name in "expected 0 <= e < 1".
std::string leaf(const std::string& path) {
  const auto dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}

bool check_range(Ctx& ctx, const Val& v, double x, const Range& r, std::string_view unit = {}) {
  if (r.contains(x)) return true;
  const std::string u = unit.empty() ? std::string() : " " + std::string(unit);
  ctx.error(v, "out of range: expected " + r.text(leaf(v.path), unit) + ", got " + fmt_num(x) + u);
  return false;
}

// Optional or required fields of a mapping, written into `out` when valid.
// Each returns false if the field was given but invalid (or required and
// missing).

bool number_field(Ctx& ctx, Map& m, std::string_view key, double& out, const Range& r,
                  std::string_view unit = {}, bool required = false) {
  const Val* v = required ? m.require(key, "a number") : m.find(key);
  if (v == nullptr) return !required;
  const auto x = read_number(ctx, *v);
  if (!x || !check_range(ctx, *v, *x, r, unit)) return false;
  out = *x;
  return true;
}

bool int_field(Ctx& ctx, Map& m, std::string_view key, int& out, std::int64_t lo, std::int64_t hi,
               std::string note = {}) {
  const Val* v = m.find(key);
  if (v == nullptr) return true;
  const auto x = read_integer(ctx, *v);
  if (!x) return false;
  if (*x < lo || *x > hi) {
    const bool bounded = hi < std::numeric_limits<int>::max();
    std::string expect =
        bounded ? std::to_string(lo) + " <= " + leaf(v->path) + " <= " + std::to_string(hi)
                : leaf(v->path) + " >= " + std::to_string(lo);
    if (!note.empty()) expect += " (" + note + ")";
    ctx.error(*v, "out of range: expected an integer " + expect + ", got " + std::to_string(*x));
    return false;
  }
  out = static_cast<int>(*x);
  return true;
}

bool bool_field(Ctx& ctx, Map& m, std::string_view key, bool& out) {
  const Val* v = m.find(key);
  if (v == nullptr) return true;
  const auto b = read_bool(ctx, *v);
  if (!b) return false;
  out = *b;
  return true;
}

constexpr std::string_view kDurationHint =
    "a duration such as 90s, 30m, 6h, 1.5d or a number of seconds";

std::optional<double> read_duration(Ctx& ctx, const Val& v, bool allow_zero) {
  if (!v.node.IsScalar()) {
    ctx.error(v, "expected " + std::string(kDurationHint) + ", got " + describe(v.node));
    return std::nullopt;
  }
  const std::string& text = v.node.Scalar();
  const std::string name = leaf(v.path);
  const std::string expect = allow_zero ? name + " >= 0 s" : name + " > 0 s";
  // The text as written, with " s" for a plain number of seconds.
  const bool plain = !text.empty() && text.back() >= '0' && text.back() <= '9';
  const std::string as_written = plain ? text + " s" : text;
  double seconds = 0.0;
  try {
    seconds = io::parse_duration_s(text);
  } catch (const std::invalid_argument&) {
    if (!text.empty() && text.front() == '-') {
      try {
        (void)io::parse_duration_s(std::string_view(text).substr(1));
        ctx.error(v, "out of range: expected " + expect + ", got " + as_written);
        return std::nullopt;
      } catch (const std::invalid_argument&) {
      }
    }
    ctx.error(v, "expected " + std::string(kDurationHint) + ", got " + describe(v.node));
    return std::nullopt;
  }
  if (!allow_zero && seconds <= 0.0) {
    ctx.error(v, "out of range: expected " + expect + ", got " + as_written);
    return std::nullopt;
  }
  return seconds;
}

bool duration_field(Ctx& ctx, Map& m, std::string_view key, double& out, bool allow_zero,
                    bool required = false) {
  const Val* v = required ? m.require(key, kDurationHint) : m.find(key);
  if (v == nullptr) return !required;
  const auto d = read_duration(ctx, *v, allow_zero);
  if (!d) return false;
  out = *d;
  return true;
}

constexpr std::string_view kUtcHint = "a UTC time such as 2024-05-08T00:00:00Z";

std::optional<astro::TimeTT> read_utc(Ctx& ctx, const Val& v) {
  if (!v.node.IsScalar()) {
    ctx.error(v, "expected " + std::string(kUtcHint) + ", got " + describe(v.node));
    return std::nullopt;
  }
  try {
    return astro::tt_from_utc_string(v.node.Scalar());
  } catch (const std::out_of_range&) {
    ctx.error(v, "out of range: UTC before 1972-01-01 is not supported, got " + describe(v.node));
  } catch (const std::exception&) {
    ctx.error(v, "expected " + std::string(kUtcHint) + ", got " + describe(v.node));
  }
  return std::nullopt;
}

// An instant: UTC text, or an offset from the scenario epoch ("3h", 5400).
// Returns nullopt without a diagnostic for an offset when the epoch itself
// is invalid (that was reported already).
std::optional<astro::TimeTT> read_instant(Ctx& ctx, const Val& v,
                                          const std::optional<astro::TimeTT>& epoch) {
  constexpr std::string_view hint =
      "a UTC time such as 2024-05-08T03:00:00Z or an offset from the epoch such as 3h or 5400";
  if (!v.node.IsScalar()) {
    ctx.error(v, "expected " + std::string(hint) + ", got " + describe(v.node));
    return std::nullopt;
  }
  const std::string& text = v.node.Scalar();
  try {
    const double offset_s = io::parse_duration_s(text);
    if (!epoch) return std::nullopt;
    return epoch->plus_seconds(offset_s);
  } catch (const std::invalid_argument&) {
  }
  try {
    return astro::tt_from_utc_string(text);
  } catch (const std::out_of_range&) {
    ctx.error(v, "out of range: UTC before 1972-01-01 is not supported, got " + describe(v.node));
  } catch (const std::exception&) {
    ctx.error(v, "expected " + std::string(hint) + ", got " + describe(v.node));
  }
  return std::nullopt;
}

// A list of exactly n finite numbers.
template <int N>
std::optional<Eigen::Matrix<double, N, 1>> read_vector(Ctx& ctx, const Val& v,
                                                       std::string_view what) {
  const std::string expect = "a list of " + std::to_string(N) + " numbers " + std::string(what);
  if (!v.node.IsSequence()) {
    ctx.error(v, "expected " + expect + ", got " + describe(v.node));
    return std::nullopt;
  }
  if (v.node.size() != static_cast<std::size_t>(N)) {
    ctx.error(v, "expected " + expect + ", got " + std::to_string(v.node.size()) + " item" +
                     (v.node.size() == 1 ? "" : "s"));
    return std::nullopt;
  }
  Eigen::Matrix<double, N, 1> out;
  bool ok = true;
  for (int k = 0; k < N; ++k) {
    const YAML::Node n = v.node[static_cast<std::size_t>(k)];
    Loc loc = loc_of(n);
    if (loc.line == 0) loc = v.loc;
    const auto x = read_number(ctx, Val{n, loc, v.path + "[" + std::to_string(k) + "]"});
    if (x) {
      out[k] = *x;
    } else {
      ok = false;
    }
  }
  if (!ok) return std::nullopt;
  return out;
}

std::string utc_text(astro::TimeTT t) {
  return astro::utc_string(t, 3);
}

// ---------------------------------------------------------------------------
// The scenario document

class Parser {
 public:
  Parser(Ctx& ctx, Scenario& s) : ctx_(ctx), s_(s) {}

  void parse(const Val& root) {
    Map top(ctx_, root,
            {"name", "description", "epoch", "epoch_window", "phase_window_deg", "duration", "step", "seed", "force_model",
             "spacecraft", "observers", "crosslink", "tuning", "maneuvers", "faults"});
    if (!top.ok()) return;

    if (const Val* v = top.require("name", "a scenario name such as starling-pse")) {
      if (auto name = read_identifier(ctx_, *v, "a scenario name", /*allow_dot=*/true)) {
        s_.name = *name;
      }
    }
    if (const Val* v = top.find("description")) {
      if (auto d = read_string(ctx_, *v, "a text")) s_.description = *d;
    }
    if (const Val* v = top.require("epoch", kUtcHint)) {
      epoch_ = read_utc(ctx_, *v);
      if (epoch_) s_.epoch = *epoch_;
    }
    if (duration_field(ctx_, top, "epoch_window", s_.epoch_window_s, /*allow_zero=*/true) &&
        s_.epoch_window_s > Scenario::kMaxEpochWindowS) {
      ctx_.error(*top.find("epoch_window"),
                 "out of range: expected at most 30 days, got " + fmt_num(s_.epoch_window_s) + " s");
    }
    number_field(ctx_, top, "phase_window_deg", s_.phase_window_deg, closed(0.0, 360.0), "deg");
    duration_ok_ =
        duration_field(ctx_, top, "duration", s_.duration_s, false, true) && top.has("duration");
    if (duration_field(ctx_, top, "step", s_.step_s, false) && duration_ok_ &&
        s_.step_s > s_.duration_s) {
      if (top.has("step")) {
        ctx_.error(*top.find("step"), "out of range: expected step <= duration (" +
                                          fmt_num(s_.duration_s) + " s), got " +
                                          fmt_num(s_.step_s) + " s");
      } else {
        ctx_.error(*top.find("duration"), "out of range: expected duration >= step (" +
                                              fmt_num(s_.step_s) + " s, the default), got " +
                                              fmt_num(s_.duration_s) + " s");
      }
    }
    if (const Val* v = top.find("seed")) parse_seed(*v);
    if (const Val* v = top.find("force_model")) parse_force_model(*v);
    // Space weather days count from the epoch; its variation draws from the seed (set_seed below).
    for (auto* f : {&s_.force_model, &s_.onboard_force_model}) {
      if (epoch_) f->space_weather.start = *epoch_;
    }

    if (const Val* v = top.require("spacecraft", "a list of spacecraft")) parse_spacecraft(*v);
    if (const Val* v = top.require("observers", "a list of observers")) parse_observers(*v);
    if (const Val* v = top.find("crosslink")) parse_crosslink(*v);
    if (const Val* v = top.find("tuning")) parse_tuning(*v);
    if (const Val* v = top.find("maneuvers")) parse_maneuvers(*v);
    if (const Val* v = top.find("faults")) parse_faults(*v);

    check_observer_modes();
    resolve_orbits();
    // Every instant above was read against the file's epoch; the run's is drawn from the seed.
    s_.epoch_nominal = s_.epoch;
    if (ctx_.count() == 0) set_seed(s_, s_.seed);
  }

 private:
  struct ScInfo {
    Val orbit;  // the orbit mapping (kepler / qns / relative)
    Val chief;  // relative.chief (kRelative only)
    bool orbit_ok = false;
  };
  struct ObsInfo {
    Val mode;
    bool gnss_explicit = false;
    Val gnss_enabled;
    bool coarse_orbit_explicit = false;
    Val coarse_orbit;
  };

  // --- top-level scalars -------------------------------------------------

  void parse_seed(const Val& v) {
    if (is_plain_scalar(v.node)) {
      const std::string& t = v.node.Scalar();
      std::uint64_t seed = 0;
      const auto res = std::from_chars(t.data(), t.data() + t.size(), seed);
      if (!t.empty() && res.ec == std::errc{} && res.ptr == t.data() + t.size()) {
        s_.seed = seed;
        return;
      }
    }
    if (const auto x = read_integer(ctx_, v)) {  // reports non-integers
      ctx_.error(v, "out of range: expected an integer seed >= 0, got " + std::to_string(*x));
    }
  }

  void parse_force_model(const Val& v) {
    // Two sides, or one block for both. A split block's truth side starts
    // from the flight-like world, its onboard side from the paper's model.
    if (v.node.IsMap() && (v.node["truth"] || v.node["onboard"])) {
      Map m(ctx_, v, {"truth", "onboard"});
      if (!m.ok()) return;
      s_.force_model = dynamics::ForceModelOptions::flight_like_truth();
      if (const Val* t = m.find("truth")) parse_force_side(*t, s_.force_model);
      if (const Val* o = m.find("onboard")) {
        parse_force_side(*o, s_.onboard_force_model);
        // The seed draws the truth's density error: an onboard model with
        // one would know the world's atmosphere to the percent.
        if (s_.onboard_force_model.space_weather.density_error_sigma > 0.0) {
          ctx_.error(*o, "space_weather.density_error_sigma is the world's error against its atmosphere model, "
                         "drawn from the run's seed: set it on the truth side only");
        }
      }
      return;
    }
    parse_force_block(v, s_.force_model);
    s_.onboard_force_model = s_.force_model;
  }

  // One side of a split block: a mapping of force keys over the side's
  // defaults, or a named model (flight-like, paper).
  void parse_force_side(const Val& v, dynamics::ForceModelOptions& f) {
    if (v.node.IsScalar()) {
      const std::string& name = v.node.Scalar();
      if (name == "flight-like") {
        f = dynamics::ForceModelOptions::flight_like_truth();
      } else if (name == "paper") {
        f = dynamics::ForceModelOptions{};
      } else {
        ctx_.error(v, "expected a mapping of force model keys, flight-like or paper, got " + describe(v.node));
      }
      return;
    }
    parse_force_block(v, f);
  }

  void parse_force_block(const Val& v, dynamics::ForceModelOptions& f) {
    Map m(ctx_, v,
          {"gravity_degree", "gravity_order", "drag", "sun", "moon", "srp", "shadow",
           "harris_priester_exponent", "harris_priester_lag_deg", "atmosphere", "space_weather"});
    if (!m.ok()) return;
    const bool degree_ok = int_field(ctx_, m, "gravity_degree", f.gravity_degree, 0,
                                     kMaxGravityDegree, "the shipped GGM01S field");
    // A degree alone means a full N x N field.
    if (degree_ok && m.has("gravity_degree") && !m.has("gravity_order")) {
      f.gravity_order = f.gravity_degree;
    }
    if (int_field(ctx_, m, "gravity_order", f.gravity_order, 0, kMaxGravityDegree) && degree_ok &&
        f.gravity_order > f.gravity_degree) {
      const Val* o = m.find("gravity_order");
      ctx_.error(o != nullptr ? *o : m.self(),
                 "out of range: expected gravity_order <= gravity_degree (" +
                     std::to_string(f.gravity_degree) + "), got " +
                     std::to_string(f.gravity_order));
    }
    bool_field(ctx_, m, "drag", f.drag);
    bool_field(ctx_, m, "sun", f.sun);
    bool_field(ctx_, m, "moon", f.moon);
    bool_field(ctx_, m, "srp", f.srp);
    if (const Val* sh = m.find("shadow")) {
      const auto t = read_string(ctx_, *sh, "conical or cylindrical");
      if (t && *t == "conical") {
        f.shadow = dynamics::ShadowModel::kConical;
      } else if (t && *t == "cylindrical") {
        f.shadow = dynamics::ShadowModel::kCylindrical;
      } else if (t) {
        ctx_.error(*sh, "expected conical or cylindrical, got " + describe(sh->node));
      }
    }
    number_field(ctx_, m, "harris_priester_exponent", f.atmosphere.cosine_exponent,
                 closed(2.0, 6.0, "2 low inclination, 6 polar orbits"));
    double lag_deg = f.atmosphere.lag_angle_rad * astro::kRadToDeg;
    if (number_field(ctx_, m, "harris_priester_lag_deg", lag_deg, closed(0.0, 90.0), "deg")) {
      f.atmosphere.lag_angle_rad = lag_deg * astro::kDegToRad;
    }
    if (const Val* av = m.find("atmosphere")) {
      const auto t = read_string(ctx_, *av, "harris-priester or jacchia-scaled-harris-priester");
      if (t && *t == "harris-priester") {
        f.atmosphere_model = dynamics::AtmosphereModel::kHarrisPriester;
      } else if (t && *t == "jacchia-scaled-harris-priester") {
        f.atmosphere_model = dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester;
      } else if (t) {
        ctx_.error(*av, "expected harris-priester or jacchia-scaled-harris-priester, got " + describe(av->node));
      }
    }
    if (const Val* wv = m.find("space_weather")) {
      if (f.atmosphere_model != dynamics::AtmosphereModel::kJacchiaScaledHarrisPriester) {
        ctx_.error(*wv, "space_weather drives the jacchia-scaled-harris-priester atmosphere only: set "
                        "atmosphere: jacchia-scaled-harris-priester (Harris-Priester has one mean activity)");
      }
      parse_space_weather(*wv, f.space_weather);
    }
  }

  void parse_space_weather(const Val& v, dynamics::SpaceWeather& w) {
    Map m(ctx_, v,
          {"f107_sfu", "f107_81day_sfu", "kp", "daily", "f107_daily_sigma_sfu", "kp_daily_sigma",
           "density_error_sigma", "density_error_time_s"});
    if (!m.ok()) return;
    number_field(ctx_, m, "f107_sfu", w.f107_sfu, positive(), "sfu");
    number_field(ctx_, m, "f107_81day_sfu", w.f107_81day_sfu, positive(), "sfu");
    number_field(ctx_, m, "kp", w.kp, closed(0.0, 9.0));
    number_field(ctx_, m, "f107_daily_sigma_sfu", w.f107_daily_sigma_sfu, non_negative("0 = off"), "sfu");
    number_field(ctx_, m, "kp_daily_sigma", w.kp_daily_sigma, non_negative("0 = off"));
    number_field(ctx_, m, "density_error_sigma", w.density_error_sigma, closed(0.0, 1.0, "0 = off"));
    number_field(ctx_, m, "density_error_time_s", w.density_error_time_s, closed(60.0, 864000.0), "s");
    if (const Val* dv = m.find("daily")) {
      const auto list = items(ctx_, *dv, "days {f107_sfu, kp}");
      if (!list) return;
      w.daily.clear();
      for (const Val& item : *list) {
        Map dm(ctx_, item, {"f107_sfu", "kp"});
        if (!dm.ok()) continue;
        dynamics::SpaceWeather::Day day;
        bool ok = number_field(ctx_, dm, "f107_sfu", day.f107_sfu, positive(), "sfu", true);
        ok &= number_field(ctx_, dm, "kp", day.kp, closed(0.0, 9.0), {}, true);
        if (ok) w.daily.push_back(day);
      }
    }
  }

  // --- spacecraft ----------------------------------------------------------

  bool angle_field(Map& m, std::string_view key, double& out_rad, const Range& r) {
    double deg = 0.0;
    if (!number_field(ctx_, m, key, deg, r, "deg", /*required=*/true)) return false;
    out_rad = deg * astro::kDegToRad;
    return true;
  }

  bool semi_major_axis(Map& m, double& a_m) {
    double a_km = 0.0;
    const Range r{kMinRadius_m / 1e3, kInf, false, false, "Earth radius + 100 km"};
    if (!number_field(ctx_, m, "a_km", a_km, r, "km", true)) return false;
    a_m = a_km * 1e3;
    return true;
  }

  void check_perigee(const Map& m, double a_m, double e) {
    const double rp = a_m * (1.0 - e);
    if (rp < kMinRadius_m) {
      ctx_.error(m.self(),
                 "out of range: perigee altitude " + fmt_num((rp - astro::kRadiusEarth_m) / 1e3) +
                     " km is below 100 km (a_km (1 - e) must be >= " + fmt_num(kMinRadius_m / 1e3) +
                     ")");
    }
  }

  bool parse_kepler(const Val& v, astro::KeplerElements& k) {
    Map m(ctx_, v, {"a_km", "e", "i_deg", "raan_deg", "argp_deg", "M_deg"});
    if (!m.ok()) return false;
    const std::size_t before = ctx_.count();
    const bool a_ok = semi_major_axis(m, k.a_m);
    const bool e_ok = number_field(ctx_, m, "e", k.e, Range{0.0, 1.0, false, true}, {}, true);
    angle_field(m, "i_deg", k.i_rad, closed(0.0, 180.0));
    angle_field(m, "raan_deg", k.raan_rad, closed(-360.0, 360.0));
    angle_field(m, "argp_deg", k.argp_rad, closed(-360.0, 360.0));
    angle_field(m, "M_deg", k.M_rad, closed(-360.0, 360.0));
    if (a_ok && e_ok) check_perigee(m, k.a_m, k.e);
    return ctx_.count() == before;
  }

  bool parse_qns(const Val& v, astro::QnsElements& q) {
    Map m(ctx_, v, {"a_km", "ex", "ey", "i_deg", "raan_deg", "u_deg"});
    if (!m.ok()) return false;
    const std::size_t before = ctx_.count();
    const bool a_ok = semi_major_axis(m, q.a_m);
    const Range ecc{-1.0, 1.0, true, true};
    const bool ex_ok = number_field(ctx_, m, "ex", q.ex, ecc, {}, true);
    const bool ey_ok = number_field(ctx_, m, "ey", q.ey, ecc, {}, true);
    angle_field(m, "i_deg", q.i_rad, closed(0.0, 180.0));
    angle_field(m, "raan_deg", q.raan_rad, closed(-360.0, 360.0));
    angle_field(m, "u_deg", q.u_rad, closed(-360.0, 360.0));
    if (ex_ok && ey_ok) {
      const double e = std::hypot(q.ex, q.ey);
      if (e >= 1.0) {
        ctx_.error(m.self(),
                   "out of range: expected 0 <= e = sqrt(ex^2 + ey^2) < 1, got " + fmt_num(e));
      } else if (a_ok) {
        check_perigee(m, q.a_m, e);
      }
    }
    return ctx_.count() == before;
  }

  bool parse_relative(const Val& v, InitialOrbit& o, ScInfo& info) {
    Map m(ctx_, v, {"chief", "roe_m", "roe_type"});
    if (!m.ok()) return false;
    if (const Val* t = m.find("roe_type")) {
      const auto type = read_string(ctx_, *t, "osculating or mean");
      if (type && *type == "mean") {
        o.mean_roe = true;
      } else if (type && *type != "osculating") {
        ctx_.error(*t, "expected osculating or mean, got " + describe(t->node));
      }
    }
    const std::size_t before = ctx_.count();
    if (const Val* c = m.require("chief", "the id of another spacecraft")) {
      if (auto id = read_identifier(ctx_, *c, "a spacecraft id")) {
        o.chief = *id;
        info.chief = *c;
      }
    }
    if (const Val* r = m.require("roe_m", "[da, dlambda, dex, dey, dix, diy] times a, in m")) {
      if (auto roe = read_vector<6>(ctx_, *r, "[da, dlambda, dex, dey, dix, diy] in m")) {
        o.a_droe_m = *roe;
      }
    }
    return ctx_.count() == before;
  }

  // Physical properties (truth at spacecraft[], the uplinked nominal values
  // at spacecraft[].onboard).
  void parse_properties(Map& m, dynamics::SpacecraftProperties& p) {
    number_field(ctx_, m, "mass_kg", p.mass_kg, positive(), "kg");
    number_field(ctx_, m, "drag_area_m2", p.drag_area_m2, positive(), "m^2");
    number_field(ctx_, m, "cd", p.cd, positive());
    number_field(ctx_, m, "srp_area_m2", p.srp_area_m2, positive(), "m^2");
    number_field(ctx_, m, "cr", p.cr, positive());
  }

  void parse_spacecraft(const Val& v) {
    const auto list = items(ctx_, v, "spacecraft");
    if (!list) return;
    if (list->empty()) {
      ctx_.error(v, "expected at least one spacecraft, got an empty list");
      return;
    }
    spacecraft_listed_ = true;
    for (const Val& item : *list) {
      Map m(ctx_, item,
            {"id", "kepler", "qns", "relative", "mass_kg", "drag_area_m2", "cd", "srp_area_m2",
             "cr", "onboard", "drag_area_variation"});
      if (!m.ok()) continue;
      SpacecraftConfig sc;
      ScInfo info;
      std::optional<std::string> id;
      if (const Val* idv = m.require("id", "a spacecraft id such as SV4")) {
        id = read_identifier(ctx_, *idv, "a spacecraft id");
        // The wire bounds ids to 31 characters and the longest name built
        // from one ("observer-<id>", "<id>-target-<k>") must fit.
        if (id && id->size() > kMaxSpacecraftIdChars) {
          ctx_.error(*idv, "expected a spacecraft id of at most " + std::to_string(kMaxSpacecraftIdChars) +
                               " characters, got " + std::to_string(id->size()) + " (" + quote(*id) + ")");
          id.reset();
        }
        if (id) {
          if (const auto it = sc_loc_.find(*id); it != sc_loc_.end()) {
            ctx_.error(*idv, "duplicate spacecraft id " + quote(*id) + " (first defined at line " +
                                 std::to_string(it->second.line) + ")");
            id.reset();
          } else {
            sc_loc_.emplace(*id, idv->loc);
          }
        }
      }
      // Exactly one orbit.
      std::vector<std::string_view> kinds;
      for (const std::string_view k : {"kepler", "qns", "relative"}) {
        if (m.has(k)) kinds.push_back(k);
      }
      if (kinds.empty()) {
        ctx_.error(item.loc, item.path,
                   "missing orbit: expected exactly one of kepler, qns or relative");
      } else if (kinds.size() > 1) {
        ctx_.error(m.key_loc(kinds[1]), m.child_path(kinds[1]),
                   "expected exactly one of kepler, qns or relative, got both " +
                       std::string(kinds[0]) + " and " + std::string(kinds[1]));
      } else {
        info.orbit = *m.find(kinds[0]);
        if (kinds[0] == "kepler") {
          sc.orbit.kind = InitialOrbit::Kind::kKepler;
          info.orbit_ok = parse_kepler(info.orbit, sc.orbit.kepler);
        } else if (kinds[0] == "qns") {
          sc.orbit.kind = InitialOrbit::Kind::kQns;
          info.orbit_ok = parse_qns(info.orbit, sc.orbit.qns);
        } else {
          sc.orbit.kind = InitialOrbit::Kind::kRelative;
          info.orbit_ok = parse_relative(info.orbit, sc.orbit, info);
        }
      }
      parse_properties(m, sc.properties);
      number_field(ctx_, m, "drag_area_variation", sc.properties.drag_area_variation,
                   Range{0.0, 1.0, false, true, "A = drag_area_m2 (1 + f cos 2u)"});
      if (const Val* ov = m.find("onboard")) {
        Map om(ctx_, *ov, {"mass_kg", "drag_area_m2", "cd", "srp_area_m2", "cr"});
        if (om.ok()) parse_properties(om, sc.onboard_properties);
      }
      if (!id) {
        all_orbits_ok_ = false;
        continue;
      }
      sc.id = *id;
      if (!info.orbit_ok) all_orbits_ok_ = false;
      s_.spacecraft.push_back(std::move(sc));
      sc_info_.push_back(std::move(info));
    }
    // Relative chiefs: known, and no cycles.
    for (std::size_t k = 0; k < s_.spacecraft.size(); ++k) {
      const auto& sc = s_.spacecraft[k];
      if (sc.orbit.kind != InitialOrbit::Kind::kRelative || sc.orbit.chief.empty()) continue;
      if (!check_spacecraft_ref(sc.orbit.chief, sc_info_[k].chief, "chief")) {
        all_orbits_ok_ = false;
      }
    }
    check_relative_cycles();
  }

  [[nodiscard]] std::string known_ids() const {
    std::string s;
    for (const auto& sc : s_.spacecraft) s += (s.empty() ? "" : ", ") + sc.id;
    return s.empty() ? "none" : s;
  }

  // Reports an id that names no spacecraft. Silent when the spacecraft list
  // itself was unusable (that was reported already).
  bool check_spacecraft_ref(const std::string& id, const Val& where, std::string_view role) {
    if (!spacecraft_listed_ || sc_loc_.count(id) != 0) return true;
    ctx_.error(where, "unknown spacecraft " + quote(id) + " as " + std::string(role) +
                          " (spacecraft defined: " + known_ids() + ")");
    return false;
  }

  void check_relative_cycles() {
    std::map<std::string, std::string> chief_of;
    for (const auto& sc : s_.spacecraft) {
      if (sc.orbit.kind == InitialOrbit::Kind::kRelative && !sc.orbit.chief.empty()) {
        chief_of[sc.id] = sc.orbit.chief;
      }
    }
    std::set<std::string> reported;
    for (std::size_t k = 0; k < s_.spacecraft.size(); ++k) {
      const std::string& start = s_.spacecraft[k].id;
      if (chief_of.count(start) == 0 || reported.count(start) != 0) continue;
      std::vector<std::string> chain{start};
      std::string cur = start;
      while (chief_of.count(cur) != 0) {
        cur = chief_of.at(cur);
        if (cur == start) {  // back where we began: a cycle, reported at its first member
          std::string text;
          for (const auto& c : chain) text += c + " -> ";
          text += start;
          reported.insert(chain.begin(), chain.end());
          ctx_.error(sc_info_[k].chief,
                     "relative orbit chain has a cycle: " + text +
                         " (one spacecraft of a chain needs an absolute kepler or qns orbit)");
          all_orbits_ok_ = false;
          break;
        }
        // Leads into a cycle that does not contain `start`: reported at that cycle.
        if (std::find(chain.begin(), chain.end(), cur) != chain.end()) break;
        chain.push_back(cur);
      }
    }
  }

  // --- observers -----------------------------------------------------------

  void parse_windows(const Val& v, std::vector<TimeWindow>& out) {
    const auto list = items(ctx_, v, "outage windows {start, end}");
    if (!list) return;
    for (const Val& item : *list) {
      Map m(ctx_, item, {"start", "end"});
      if (!m.ok()) continue;
      if (auto w = parse_window(m)) out.push_back(*w);
    }
  }

  std::optional<TimeWindow> parse_window(Map& m) {
    const Val* sv = m.require("start", "a UTC time or an offset from the epoch");
    const Val* ev = m.require("end", "a UTC time or an offset from the epoch");
    std::optional<astro::TimeTT> start, end;
    if (sv != nullptr) start = read_instant(ctx_, *sv, epoch_);
    if (ev != nullptr) end = read_instant(ctx_, *ev, epoch_);
    if (!start || !end) return std::nullopt;
    if (*end <= *start) {
      ctx_.error(*ev, "out of range: expected the window's end after its start (" +
                          utc_text(*start) + "), got " + utc_text(*end));
      return std::nullopt;
    }
    return TimeWindow{*start, *end};
  }

  void parse_camera(const Val& v, CameraConfig& c) {
    Map m(ctx_, v, {"model", "boresight", "cadence", "pointing_error_deg", "jitter_deg", "profile",
                    "time_tag_correction_s", "stellar_aberration"});
    if (!m.ok()) return;
    if (const Val* mv = m.find("model")) {
      if (auto model =
              read_identifier(ctx_, *mv, "a camera model name (file stem in config/cameras/)")) {
        c.model = *model;
      }
    }
    if (const Val* b = m.find("boresight")) {
      const auto t = read_string(ctx_, *b, "+velocity or -velocity");
      if (t && *t == "+velocity") {
        c.boresight = astro::Boresight::kPlusVelocity;
      } else if (t && *t == "-velocity") {
        c.boresight = astro::Boresight::kMinusVelocity;
      } else if (t) {
        ctx_.error(*b, "expected +velocity or -velocity, got " + describe(b->node));
      }
    }
    duration_field(ctx_, m, "cadence", c.cadence_s, false);
    number_field(ctx_, m, "pointing_error_deg", c.pointing_error_deg, Range{0.0, 90.0, false, true},
                 "deg");
    number_field(ctx_, m, "jitter_deg", c.jitter_deg, Range{0.0, 90.0, false, true}, "deg");
    number_field(ctx_, m, "time_tag_correction_s", c.time_tag_correction_s, closed(-60.0, 60.0), "s");
    bool_field(ctx_, m, "stellar_aberration", c.stellar_aberration);
    if (const Val* pv = m.find("profile")) {
      const auto t = read_string(ctx_, *pv, "nominal or flight-like");
      if (t && *t == "flight-like") {
        c.flight_like = true;
      } else if (t && *t == "nominal") {
        c.flight_like = false;
      } else if (t) {
        ctx_.error(*pv, "expected nominal or flight-like, got " + describe(pv->node));
      }
    }
  }

  void parse_gnss(const Val& v, GnssConfig& g, ObsInfo& info) {
    Map m(ctx_, v, {"enabled", "period", "sigma_position_m", "sigma_velocity_mps", "outages"});
    if (!m.ok()) return;
    if (const Val* e = m.find("enabled")) {
      info.gnss_explicit = bool_field(ctx_, m, "enabled", g.enabled);
      info.gnss_enabled = *e;
    }
    duration_field(ctx_, m, "period", g.period_s, false);
    number_field(ctx_, m, "sigma_position_m", g.sigma_position_m, non_negative(), "m");
    number_field(ctx_, m, "sigma_velocity_mps", g.sigma_velocity_mps, non_negative(), "m/s");
    if (const Val* o = m.find("outages")) parse_windows(*o, g.outages);
  }

  void parse_observers(const Val& v) {
    const auto list = items(ctx_, v, "observers");
    if (!list) return;
    if (list->empty()) {
      ctx_.error(v, "expected at least one observer, got an empty list");
      return;
    }
    std::map<std::string, Loc> seen;
    for (const Val& item : *list) {
      Map m(ctx_, item, {"spacecraft", "mode", "camera", "gnss", "apriori", "targets", "coarse_orbit"});
      if (!m.ok()) continue;
      ObserverConfig o;
      ObsInfo info;
      bool ok = true;  // an observer with a usable, new id (kept for later checks)
      if (const Val* sv = m.require("spacecraft", "the id of the observing spacecraft")) {
        if (auto id = read_identifier(ctx_, *sv, "a spacecraft id")) {
          o.spacecraft = *id;
          check_spacecraft_ref(*id, *sv, "observer");
          if (const auto it = seen.find(*id); it != seen.end()) {
            ctx_.error(*sv, "duplicate observer " + quote(*id) + " (already an observer at line " +
                                std::to_string(it->second.line) + ")");
            ok = false;
          } else {
            seen.emplace(*id, sv->loc);
          }
        } else {
          ok = false;
        }
      } else {
        ok = false;
      }
      info.mode = m.find("mode") != nullptr ? *m.find("mode") : item;
      int_field(ctx_, m, "mode", o.mode, 0, 4,
                "0 GNSS-only, 1 single observer + ground a-priori, 2 single observer + BOD, "
                "3 multi-observer + GNSS, 4 multi-observer without GNSS");
      if (const Val* c = m.find("camera")) parse_camera(*c, o.camera);
      if (const Val* g = m.find("gnss")) parse_gnss(*g, o.gnss, info);
      if (const Val* a = m.find("apriori")) {
        Map am(ctx_, *a, {"age_days"});
        if (am.ok()) {
          number_field(ctx_, am, "age_days", o.apriori.age_days, closed(0.0, 365.0), "days");
        }
      }
      if (const Val* tv = m.find("targets")) {
        if (const auto tl = items(ctx_, *tv, "targets")) {
          for (const Val& t : *tl) {
            // An id, or {id: SV2, range_km: [min, max]} (BOD's range window for it).
            const Val* idv = &t;
            std::array<double, 2> window{0.0, 0.0};
            std::optional<Map> tm;
            if (t.node.IsMap()) {
              tm.emplace(ctx_, t, std::vector<std::string_view>{"id", "range_km", "gravity_periodic_roe_m"});
              if (!tm->ok()) continue;
              idv = tm->require("id", "a spacecraft id");
              if (!idv) continue;
              if (const Val* rv = tm->find("range_km")) {
                if (const auto w = read_vector<2>(ctx_, *rv, "[min, max] in km")) {
                  if (!((*w)[0] > 0.0) || !((*w)[1] > (*w)[0])) {
                    ctx_.error(*rv, "out of range: expected 0 < min < max, got [" + fmt_num((*w)[0]) + ", " +
                                        fmt_num((*w)[1]) + "]");
                  } else {
                    window = {(*w)[0] * 1e3, (*w)[1] * 1e3};
                  }
                }
              }
            }
            std::optional<astro::Vec6> gravity_periodic;
            if (tm) {
              if (const Val* gv = tm->find("gravity_periodic_roe_m")) {
                if (const auto g = read_vector<6>(ctx_, *gv, "[da, dlambda, dex, dey, dix, diy] 1-sigma times a, in m")) {
                  if (!((*g).array() >= 0.0).all() || !((*g).array() <= 1e4).all()) {
                    ctx_.error(*gv, "out of range: expected every 1-sigma in [0, 1e4] m");
                  } else {
                    gravity_periodic = *g;
                  }
                }
              }
            }
            if (auto id = read_identifier(ctx_, *idv, "a spacecraft id")) {
              check_spacecraft_ref(*id, *idv, "target");
              if (gravity_periodic) o.target_gravity_periodic_a_roe_m[*id] = *gravity_periodic;
              if (*id == o.spacecraft) {
                ctx_.error(*idv, "an observer is not its own target: " + quote(*id));
              } else if (std::find(o.targets.begin(), o.targets.end(), *id) != o.targets.end()) {
                ctx_.error(*idv, "duplicate target " + quote(*id));
              } else {
                o.targets.push_back(*id);
                o.target_ranges_m.push_back(window);
              }
            }
          }
        }
      }
      if (const Val* c = m.find("coarse_orbit")) {
        info.coarse_orbit = *c;
        info.coarse_orbit_explicit = true;
        Map cm(ctx_, *c, {"sigma_roe_m", "error_roe_m"});
        if (cm.ok()) {
          if (const Val* e = cm.find("error_roe_m")) {
            if (auto err = read_vector<6>(ctx_, *e, "[da, dlambda, dex, dey, dix, diy] in m")) {
              if (!((*err).array().abs() <= 1e6).all()) {
                ctx_.error(*e, "out of range: expected every component within +-1e6 m");
              } else {
                o.coarse_orbit_error_a_roe_m = *err;
              }
            }
          }
          if (const Val* r = cm.require("sigma_roe_m", "[da, dlambda, dex, dey, dix, diy] 1-sigma times a, in m")) {
            if (auto sig = read_vector<6>(ctx_, *r, "[da, dlambda, dex, dey, dix, diy] in m")) {
              if (!((*sig).array() > 0.0).all() || !((*sig).array() <= 1e6).all()) {
                ctx_.error(*r, "out of range: expected every 1-sigma in (0, 1e6] m");
              } else {
                o.coarse_orbit_sigma_a_roe_m = *sig;
              }
            }
          }
        }
      }
      // Mode 4 flies without GNSS: off unless the file says otherwise (an error).
      if (o.mode == 4 && !info.gnss_explicit) o.gnss.enabled = false;
      if (ok) {
        s_.observers.push_back(std::move(o));
        obs_info_.push_back(std::move(info));
      }
    }
  }

  void check_observer_modes() {
    for (std::size_t k = 0; k < s_.observers.size(); ++k) {
      const auto& o = s_.observers[k];
      const auto& info = obs_info_[k];
      if (o.mode != 4 && info.coarse_orbit_explicit) {
        ctx_.error(info.coarse_orbit, "coarse_orbit is the starting orbit of navigation mode 4; mode " +
                                          std::to_string(o.mode) + " starts from its GNSS fixes");
      }
      if (o.mode == 4 && o.gnss.enabled) {
        ctx_.error(info.gnss_enabled,
                   "mode 4 navigates without GNSS: expected gnss.enabled: false (or omit it)");
      }
      if (o.mode >= 0 && o.mode <= 3 && !o.gnss.enabled && info.gnss_explicit) {
        ctx_.error(info.gnss_enabled,
                   "mode " + std::to_string(o.mode) +
                       " uses GNSS for the observer's absolute orbit: expected gnss.enabled: true "
                       "(mode 4 is the GNSS-free mode; use gnss.outages for gaps)");
      }
      if (o.mode >= 3) {
        if (!s_.crosslink.enabled) {
          ctx_.error(info.mode, "mode " + std::to_string(o.mode) +
                                    " fuses bearings from other observers: expected "
                                    "crosslink.enabled: true");
        }
        if (s_.observers.size() < 2) {
          ctx_.error(info.mode, "mode " + std::to_string(o.mode) +
                                    " is multi-observer: expected at least two observers, got 1");
        }
      }
    }
  }

  // --- crosslink, tuning, maneuvers, faults -------------------------------

  void parse_crosslink(const Val& v) {
    Map m(ctx_, v,
          {"enabled", "period", "latency", "max_range_km", "loss_probability", "use_remote_gnss",
           "outages"});
    if (!m.ok()) return;
    auto& c = s_.crosslink;
    bool_field(ctx_, m, "enabled", c.enabled);
    duration_field(ctx_, m, "period", c.period_s, false);
    duration_field(ctx_, m, "latency", c.latency_s, true);
    double range_km = c.max_range_m / 1e3;
    if (number_field(ctx_, m, "max_range_km", range_km, positive(), "km")) {
      c.max_range_m = range_km * 1e3;
    }
    number_field(ctx_, m, "loss_probability", c.loss_probability, closed(0.0, 1.0));
    bool_field(ctx_, m, "use_remote_gnss", c.use_remote_gnss);
    if (const Val* o = m.find("outages")) {
      const auto list = items(ctx_, *o, "link outages {from, to, start, end}");
      if (!list) return;
      for (const Val& item : *list) {
        Map om(ctx_, item, {"from", "to", "start", "end"});
        if (!om.ok()) continue;
        LinkOutage out{"*", "*", {}};
        bool ok = true;
        for (const std::string_view end : {"from", "to"}) {
          const Val* ev = om.find(end);
          if (ev == nullptr) continue;
          const auto id = read_string(ctx_, *ev, "a spacecraft id or '*'");
          if (!id) {
            ok = false;
            continue;
          }
          if (*id != "*" && !check_spacecraft_ref(*id, *ev, "link end")) ok = false;
          (end == "from" ? out.from : out.to) = *id;
        }
        if (ok && out.from != "*" && out.from == out.to) {
          ctx_.error(*om.find("to"), "expected a link between two different spacecraft, got " +
                                         quote(out.from) + " to itself");
          ok = false;
        }
        const auto w = parse_window(om);
        if (ok && w) {
          out.window = *w;
          c.outages.push_back(std::move(out));
        }
      }
    }
  }

  void parse_tuning(const Val& v) {
    Map m(ctx_, v, {"imp", "bod", "sod"});
    if (!m.ok()) return;
    auto& t = s_.tuning;
    constexpr std::int64_t kBig = std::numeric_limits<int>::max();
    if (const Val* iv = m.find("imp")) {
      Map im(ctx_, *iv,
             {"detection_sigma", "dbscan_min_points", "dbscan_radius_px", "dbscan_frames", "aided_detection_snr",
              "aided_false_alarms", "aberration_correction", "signal_history", "aided_stack_frames"});
      if (im.ok()) {
        number_field(ctx_, im, "detection_sigma", t.imp.detection_sigma, positive());
        int_field(ctx_, im, "dbscan_min_points", t.imp.dbscan_min_points, 1, kBig);
        number_field(ctx_, im, "dbscan_radius_px", t.imp.dbscan_radius_px, positive(), "px");
        int_field(ctx_, im, "dbscan_frames", t.imp.dbscan_frames, 1, kBig);
        number_field(ctx_, im, "aided_detection_snr", t.imp.aided_detection_snr, non_negative("0 = off"));
        number_field(ctx_, im, "aided_false_alarms", t.imp.aided_false_alarms,
                     closed(0.0, 0.1, "0 = the fixed aided_detection_snr"));
        bool_field(ctx_, im, "aberration_correction", t.imp.aberration_correction);
        bool_field(ctx_, im, "signal_history", t.imp.signal_history);
        int_field(ctx_, im, "aided_stack_frames", t.imp.aided_stack_frames, 0, 5);
      }
    }
    if (const Val* bv = m.find("bod")) {
      Map bm(ctx_, *bv,
             {"enabled", "period", "samples", "max_iterations", "range_min_m", "range_max_m", "min_measurements",
              "max_measurements", "batch_orbits", "max_sigma_range_fraction", "max_residual_arcsec", "check_chi2",
              "max_fit_ratio", "reinit_after_check5", "model_correction"});
      if (bm.ok()) {
        bool_field(ctx_, bm, "enabled", t.bod.enabled);
        duration_field(ctx_, bm, "period", t.bod.period_s, false);
        int_field(ctx_, bm, "samples", t.bod.samples, 5, kBig);
        int_field(ctx_, bm, "max_iterations", t.bod.max_iterations, 1, kBig);
        const bool lo = number_field(ctx_, bm, "range_min_m", t.bod.range_min_m, positive(), "m");
        const bool hi = number_field(ctx_, bm, "range_max_m", t.bod.range_max_m, positive(), "m");
        if (lo && hi && !(t.bod.range_max_m > t.bod.range_min_m)) {
          ctx_.error(bm.find("range_max_m") ? *bm.find("range_max_m") : bm.self(),
                     "out of range: expected range_max_m > range_min_m, got " + fmt_num(t.bod.range_max_m) + " and " +
                         fmt_num(t.bod.range_min_m));
        }
        const bool mn = int_field(ctx_, bm, "min_measurements", t.bod.min_measurements, 7, kBig);
        const bool mx = int_field(ctx_, bm, "max_measurements", t.bod.max_measurements, 7, kBig);
        if (mn && mx && t.bod.max_measurements < t.bod.min_measurements) {
          ctx_.error(bm.find("max_measurements") ? *bm.find("max_measurements") : bm.self(),
                     "out of range: expected max_measurements >= min_measurements, got " +
                         std::to_string(t.bod.max_measurements) + " and " + std::to_string(t.bod.min_measurements));
        }
        number_field(ctx_, bm, "batch_orbits", t.bod.batch_orbits, closed(0.25, 10.0), "orbits");
        number_field(ctx_, bm, "max_sigma_range_fraction", t.bod.max_sigma_range_fraction, positive());
        number_field(ctx_, bm, "max_residual_arcsec", t.bod.max_residual_arcsec, positive(), "arcsec");
        number_field(ctx_, bm, "check_chi2", t.bod.check_chi2, positive());
        number_field(ctx_, bm, "max_fit_ratio", t.bod.max_fit_ratio, closed(1.0, 100.0));
        bool_field(ctx_, bm, "reinit_after_check5", t.bod.reinit_after_check5);
        bool_field(ctx_, bm, "model_correction", t.bod.model_correction);
      }
    }
    if (const Val* sv = m.find("sod")) {
      Map sm(ctx_, *sv,
             {"period", "bearing_sigma_arcsec", "eps_assign", "eps_ambig",
              "max_steps_without_update", "max_large_residuals", "underweighting", "underweighting_nonlinearity",
              "adaptive_process_noise", "adaptive_targets", "adaptive_form", "adaptive_average", "adaptive_time_constant", "drag_density_error", "process_noise_scale", "nis_window", "nis_false_alarm", "time_tag",
              "ballistic", "observer_acceleration_sigma_mps2", "target_lines"});
      if (sm.ok()) {
        duration_field(ctx_, sm, "period", t.sod.period_s, false);
        number_field(ctx_, sm, "bearing_sigma_arcsec", t.sod.bearing_sigma_arcsec,
                     non_negative("0 = IMP's own 1-sigma per measurement"), "arcsec");
        const bool a_ok = number_field(ctx_, sm, "eps_assign", t.sod.eps_assign, positive());
        const bool b_ok = number_field(ctx_, sm, "eps_ambig", t.sod.eps_ambig, positive());
        if (a_ok && b_ok && !(t.sod.eps_ambig > t.sod.eps_assign)) {
          const Val* where = sm.find("eps_ambig") != nullptr    ? sm.find("eps_ambig")
                             : sm.find("eps_assign") != nullptr ? sm.find("eps_assign")
                                                                : &sm.self();
          ctx_.error(*where,
                     "out of range: expected eps_ambig > eps_assign > 0 (paper), got "
                     "eps_assign " +
                         fmt_num(t.sod.eps_assign) + ", eps_ambig " + fmt_num(t.sod.eps_ambig));
        }
        int_field(ctx_, sm, "max_steps_without_update", t.sod.max_steps_without_update, 1, kBig);
        int_field(ctx_, sm, "max_large_residuals", t.sod.max_large_residuals, 1, kBig);
        number_field(ctx_, sm, "underweighting", t.sod.underweighting, non_negative());
        number_field(ctx_, sm, "underweighting_nonlinearity", t.sod.underweighting_nonlinearity,
                     non_negative("0 = underweight while the predicted spread exceeds R"));
        bool_field(ctx_, sm, "adaptive_process_noise", t.sod.adaptive_process_noise);
        bool_field(ctx_, sm, "adaptive_targets", t.sod.adaptive_targets);
        using F = SodTuning::AdaptiveForm;
        using A = SodTuning::AdaptiveAverage;
        if (const Val* fv = sm.find("adaptive_form")) {
          choice<F>(ctx_, *fv, "diagonal or block", {{"diagonal", F::kDiagonal}, {"block", F::kBlock}},
                    t.sod.adaptive_form);
        }
        if (const Val* av = sm.find("adaptive_average")) {
          choice<A>(ctx_, *av, "clamped or unclamped", {{"clamped", A::kClamped}, {"unclamped", A::kUnclamped}},
                    t.sod.adaptive_average);
        }
        if (duration_field(ctx_, sm, "adaptive_time_constant", t.sod.adaptive_time_constant_s, false) &&
            t.sod.adaptive_time_constant_s > SodTuning::kMaxAdaptiveTimeConstantS) {
          ctx_.error(*sm.find("adaptive_time_constant"),
                     "out of range: expected at most 30 days, got " + fmt_num(t.sod.adaptive_time_constant_s) + " s");
        }
        number_field(ctx_, sm, "process_noise_scale", t.sod.process_noise_scale, positive());
        number_field(ctx_, sm, "drag_density_error", t.sod.drag_density_error, Range{0.0, 10.0, true, true});
        int_field(ctx_, sm, "nis_window", t.sod.nis_window, 0, 1000);
        number_field(ctx_, sm, "nis_false_alarm", t.sod.nis_false_alarm, Range{0.0, 0.5, true, false});
        number_field(ctx_, sm, "observer_acceleration_sigma_mps2", t.sod.observer_acceleration_sigma_mps2,
                     Range{0.0, 1e-3, true, true}, "m/s^2");
        if (const Val* lv = sm.find("target_lines")) {
          using L = SodTuning::TargetLines;
          choice<L>(ctx_, *lv, "consider_observer or update_observer",
                    {{"consider_observer", L::kConsiderObserver}, {"update_observer", L::kUpdateObserver}},
                    t.sod.target_lines);
        }
        if (const Val* tv = sm.find("time_tag")) {
          Map tm(ctx_, *tv, {"estimate", "sigma_s", "drift_sigma_ppm", "senders", "senders_sigma_s"});
          if (tm.ok()) {
            if (const Val* ev = tm.find("estimate")) {
              using E = SodTuning::TimeTagEstimation;
              choice<E>(ctx_, *ev, "none, offset or drift",
                        {{"none", E::kNone}, {"offset", E::kOffset}, {"drift", E::kOffsetAndDrift}}, t.sod.time_tag);
            }
            number_field(ctx_, tm, "sigma_s", t.sod.time_tag_sigma_s, Range{0.0, 60.0, true, true}, "s");
            number_field(ctx_, tm, "drift_sigma_ppm", t.sod.time_tag_drift_sigma_ppm, Range{0.0, 1e4, true, true},
                         "ppm");
            bool_field(ctx_, tm, "senders", t.sod.time_tag_senders);
            number_field(ctx_, tm, "senders_sigma_s", t.sod.time_tag_senders_sigma_s, Range{0.0, 60.0, true, true}, "s");
          }
        }
        if (const Val* bv = sm.find("ballistic")) {
          Map bm2(ctx_, *bv, {"estimate", "sigma_fraction", "walk_fraction_per_day", "density_change_per_day"});
          if (bm2.ok()) {
            bool_field(ctx_, bm2, "estimate", t.sod.estimate_ballistic);
            number_field(ctx_, bm2, "sigma_fraction", t.sod.ballistic_sigma_fraction, Range{0.0, 10.0, true, true});
            if (bm2.find("walk_fraction_per_day")) {
              double walk = 0.0;
              number_field(ctx_, bm2, "walk_fraction_per_day", walk, Range{0.0, 10.0, false, true});
              t.sod.ballistic_walk_fraction_per_day = walk;
            }
            number_field(ctx_, bm2, "density_change_per_day", t.sod.ballistic_density_change_per_day,
                         Range{0.0, 10.0, false, false});
          }
        }
      }
    }
  }

  void parse_maneuvers(const Val& v) {
    const auto list = items(ctx_, v, "maneuvers {spacecraft, epoch, dv_rtn_mps}");
    if (!list) return;
    for (const Val& item : *list) {
      Map m(ctx_, item, {"spacecraft", "epoch", "dv_rtn_mps", "planned", "execution_sigma_fraction"});
      if (!m.ok()) continue;
      ManeuverConfig mc;
      bool ok = true;
      if (const Val* sv = m.require("spacecraft", "the id of the maneuvering spacecraft")) {
        const auto id = read_identifier(ctx_, *sv, "a spacecraft id");
        ok = id && check_spacecraft_ref(*id, *sv, "maneuvering spacecraft");
        if (id) mc.spacecraft = *id;
      } else {
        ok = false;
      }
      if (const Val* ev = m.require("epoch", "a UTC time or an offset from the epoch")) {
        const auto t = read_instant(ctx_, *ev, epoch_);
        if (t && epoch_ && duration_ok_) {
          const astro::TimeTT end = epoch_->plus_seconds(s_.duration_s);
          if (*t < *epoch_ || *t > end) {
            ctx_.error(*ev, "out of range: maneuver at " + utc_text(*t) +
                                " is outside the scenario span [" + utc_text(*epoch_) + ", " +
                                utc_text(end) + "]");
            ok = false;
          }
        }
        if (t) {
          mc.epoch = *t;
        } else {
          ok = false;
        }
      } else {
        ok = false;
      }
      bool_field(ctx_, m, "planned", mc.planned);
      number_field(ctx_, m, "execution_sigma_fraction", mc.execution_sigma_fraction, closed(0.0, 0.5));
      if (const Val* dv = m.require("dv_rtn_mps", "[dv_r, dv_t, dv_n] in m/s")) {
        if (auto x = read_vector<3>(ctx_, *dv, "[dv_r, dv_t, dv_n] in m/s")) {
          mc.dv_rtn_mps = *x;
        } else {
          ok = false;
        }
      } else {
        ok = false;
      }
      if (ok) s_.maneuvers.push_back(std::move(mc));
    }
  }

  void parse_faults(const Val& v) {
    const auto list = items(ctx_, v, "fault entries");
    if (!list) return;
    std::map<std::string, Loc> seen;
    for (const Val& item : *list) {
      Map m(ctx_, item,
            {"observer", "frame_dropout_probability", "time_tag_offset_s", "time_tag_drift_ppm",
             "time_tag_offset_sigma_s", "time_tag_drift_sigma_ppm"});
      if (!m.ok()) continue;
      FaultConfig f;
      if (const Val* ov = m.find("observer")) {
        if (auto id = read_identifier(ctx_, *ov, "an observer's spacecraft id")) {
          f.observer = *id;
          const bool is_observer =
              std::any_of(s_.observers.begin(), s_.observers.end(),
                          [&](const ObserverConfig& o) { return o.spacecraft == *id; });
          if (!is_observer && spacecraft_listed_ && !s_.observers.empty()) {
            std::string names;
            for (const auto& o : s_.observers) names += (names.empty() ? "" : ", ") + o.spacecraft;
            ctx_.error(*ov, "unknown observer " + quote(*id) + " (observers: " + names + ")");
          }
        }
      }
      const Val& where = m.find("observer") != nullptr ? *m.find("observer") : item;
      if (const auto it = seen.find(f.observer); it != seen.end()) {
        ctx_.error(where, "duplicate fault entry for " +
                              (f.observer.empty() ? std::string("all observers")
                                                  : "observer " + quote(f.observer)) +
                              " (first at line " + std::to_string(it->second.line) + ")");
      } else {
        seen.emplace(f.observer, where.loc);
      }
      number_field(ctx_, m, "frame_dropout_probability", f.frame_dropout_probability,
                   Range{0.0, 1.0, false, true});
      number_field(ctx_, m, "time_tag_offset_s", f.time_tag_offset_s, any_finite(), "s");
      number_field(ctx_, m, "time_tag_drift_ppm", f.time_tag_drift_ppm,
                   Range{-1e6, 1e6, true, true}, "ppm");
      number_field(ctx_, m, "time_tag_offset_sigma_s", f.time_tag_offset_sigma_s, Range{0.0, 60.0, false, false}, "s");
      number_field(ctx_, m, "time_tag_drift_sigma_ppm", f.time_tag_drift_sigma_ppm, Range{0.0, 1e4, false, false},
                   "ppm");
      s_.faults.push_back(std::move(f));
    }
  }

  // --- initial orbits --------------------------------------------------------

  // With every orbit valid, resolves each through its chiefs; reports states
  // that cannot be formed or whose orbit dips below 100 km.
  void resolve_orbits() {
    if (!all_orbits_ok_) return;
    for (std::size_t k = 0; k < s_.spacecraft.size(); ++k) {
      const auto& sc = s_.spacecraft[k];
      try {
        const astro::StateVector x = s_.initial_state_eci(sc.id);
        if (sc.orbit.kind != InitialOrbit::Kind::kRelative) continue;
        const astro::KeplerElements oe = astro::kepler_from_cartesian(x);
        const double rp = oe.a_m * (1.0 - oe.e);
        if (rp < kMinRadius_m) {
          ctx_.error(sc_info_[k].orbit, "out of range: the orbit this gives " + sc.id +
                                            " has perigee altitude " +
                                            fmt_num((rp - astro::kRadiusEarth_m) / 1e3) +
                                            " km, below 100 km (check roe_m)");
        }
      } catch (const std::exception& e) {
        ctx_.error(sc_info_[k].orbit,
                   "cannot form the initial state of " + sc.id + ": " + e.what());
      }
    }
  }

  Ctx& ctx_;
  Scenario& s_;
  std::optional<astro::TimeTT> epoch_;
  bool duration_ok_ = false;
  bool spacecraft_listed_ = false;
  bool all_orbits_ok_ = true;
  std::map<std::string, Loc> sc_loc_;
  std::vector<ScInfo> sc_info_;
  std::vector<ObsInfo> obs_info_;
};

// Reads, parses and validates; diagnostics in file order.
std::vector<Diagnostic> load(const std::string& path, Scenario& s) {
  Ctx ctx(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    ctx.error(Loc{}, "", "cannot open scenario file");
    return ctx.take();
  }
  std::ostringstream text;
  text << in.rdbuf();
  std::vector<YAML::Node> docs;
  try {
    docs = YAML::LoadAll(text.str());
  } catch (const YAML::Exception& e) {
    const Loc loc = e.mark.is_null() ? Loc{} : Loc{e.mark.line + 1, e.mark.column + 1};
    ctx.error(loc, "", "YAML syntax error: " + e.msg);
    return ctx.take();
  }
  if (docs.size() > 1) {
    Loc loc = loc_of(docs[1]);
    ctx.error(loc, "",
              "expected one YAML document per scenario file, got " + std::to_string(docs.size()));
  }
  const YAML::Node root = docs.empty() ? YAML::Node() : docs.front();
  Loc root_loc = loc_of(root);
  if (root_loc.line == 0) root_loc = {1, 1};
  s.source_path = path;
  Parser parser(ctx, s);
  parser.parse(Val{root, root_loc, ""});
  return ctx.take();
}

// Absolute QNS elements of a spacecraft, relative orbits resolved through
// their chiefs (depth guards against cycles in hand-built scenarios).
astro::QnsElements absolute_qns(const Scenario& s, const SpacecraftConfig& sc, std::size_t depth) {
  switch (sc.orbit.kind) {
    case InitialOrbit::Kind::kKepler:
      return astro::qns_from_kepler(sc.orbit.kepler);
    case InitialOrbit::Kind::kQns:
      return sc.orbit.qns;
    case InitialOrbit::Kind::kRelative:
      break;
  }
  if (depth > s.spacecraft.size()) {
    throw std::invalid_argument("relative orbit chain through '" + sc.id + "' has a cycle");
  }
  const astro::QnsElements chief = absolute_qns(s, s.spacecraft_by_id(sc.orbit.chief), depth + 1);
  if (sc.orbit.mean_roe) {
    const astro::QnsElements chief_mean = dynamics::mean_from_osculating(chief);
    return dynamics::osculating_from_mean(
        astro::qns_from_roe(chief_mean, astro::Roe::from_scaled_m(sc.orbit.a_droe_m, chief_mean.a_m)));
  }
  return astro::qns_from_roe(chief, astro::Roe::from_scaled_m(sc.orbit.a_droe_m, chief.a_m));
}

}  // namespace

// ---------------------------------------------------------------------------
// Scenario

bool Scenario::force_models_agree() const {
  const auto& a = force_model;
  const auto& b = onboard_force_model;
  const bool same_atmosphere =
      a.atmosphere_model == b.atmosphere_model &&
      (a.atmosphere_model == dynamics::AtmosphereModel::kHarrisPriester
           ? a.atmosphere.cosine_exponent == b.atmosphere.cosine_exponent &&
                 a.atmosphere.lag_angle_rad == b.atmosphere.lag_angle_rad
           : a.space_weather == b.space_weather &&
                 a.jacchia.reference_temperature_K == b.jacchia.reference_temperature_K &&
                 a.jacchia.semiannual == b.jacchia.semiannual);
  return a.gravity_degree == b.gravity_degree && a.gravity_order == b.gravity_order && a.drag == b.drag &&
         a.sun == b.sun && a.moon == b.moon && a.srp == b.srp && a.shadow == b.shadow &&
         (!a.drag || same_atmosphere);
}

const SpacecraftConfig& Scenario::spacecraft_by_id(const std::string& id) const {
  for (const auto& sc : spacecraft) {
    if (sc.id == id) return sc;
  }
  throw std::out_of_range("scenario '" + name + "' has no spacecraft '" + id + "'");
}

astro::StateVector Scenario::initial_state_eci(const std::string& id) const {
  const SpacecraftConfig& sc = spacecraft_by_id(id);
  if (sc.orbit.kind == InitialOrbit::Kind::kKepler) {
    return astro::cartesian_from_kepler(sc.orbit.kepler);
  }
  return astro::cartesian_from_qns(absolute_qns(*this, sc, 0));
}

double Scenario::reference_period_s() const {
  if (observers.empty()) {
    throw std::out_of_range("scenario '" + name + "' has no observers");
  }
  const SpacecraftConfig& sc = spacecraft_by_id(observers.front().spacecraft);
  return astro::orbit_period_s(absolute_qns(*this, sc, 0).a_m);
}

astro::Vec3 executed_maneuver_dv(const Scenario& s, std::size_t index) {
  const ManeuverConfig& m = s.maneuvers.at(index);
  if (!(m.execution_sigma_fraction > 0.0)) return m.dv_rtn_mps;
  std::seed_seq seq{static_cast<std::uint64_t>(s.seed), std::uint64_t{0x6d616e}, std::uint64_t{index}};
  std::mt19937_64 rng(seq);
  std::normal_distribution<double> g(0.0, m.execution_sigma_fraction);
  const double scale = 1.0 + g(rng);
  // Pointing error: a small rotation about two axes normal to the delta-v.
  const astro::Vec3 u = m.dv_rtn_mps.normalized();
  const astro::Vec3 e1 = u.unitOrthogonal(), e2 = u.cross(e1);
  const astro::Vec3 dir = (u + g(rng) * e1 + g(rng) * e2).normalized();
  return scale * m.dv_rtn_mps.norm() * dir;
}

namespace {

// Moves the run's epoch and every instant the file gives by dt_s.
void shift_instants(Scenario& s, double dt_s) {
  if (dt_s == 0.0) return;
  const auto shift = [dt_s](astro::TimeTT& t) { t = t.plus_seconds(dt_s); };
  shift(s.epoch);
  for (auto* f : {&s.force_model, &s.onboard_force_model}) shift(f->space_weather.start);
  for (auto& m : s.maneuvers) shift(m.epoch);
  for (auto& o : s.observers) {
    for (auto& w : o.gnss.outages) {
      shift(w.start);
      shift(w.end);
    }
  }
  for (auto& l : s.crosslink.outages) {
    shift(l.window.start);
    shift(l.window.end);
  }
}

// A uniform draw in [0, 1) from a stream of the seed of its own (tag).
double uniform_from_seed(std::uint64_t seed, std::uint64_t tag) {
  std::seed_seq seq{seed, tag};
  std::mt19937_64 rng(seq);
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// The epoch's offset in [0, window): whole seconds.
double draw_epoch_offset_s(std::uint64_t seed, double window_s) {
  if (!(window_s > 0.0)) return 0.0;
  return std::floor(uniform_from_seed(seed, 0x65706f6368) * window_s);  // "epoch"
}

void draw_epoch(Scenario& s) {
  const double offset_s = draw_epoch_offset_s(s.seed, s.epoch_window_s);
  shift_instants(s, offset_s - s.epoch_offset_s);
  s.epoch_offset_s = offset_s;
}

// The orbit phase in [0, window) deg.
double draw_phase_offset_deg(std::uint64_t seed, double window_deg) {
  if (!(window_deg > 0.0)) return 0.0;
  return uniform_from_seed(seed, 0x7068617365) * window_deg;  // "phase"
}

// Turns every orbit given in absolute elements by the drawn phase along
// itself (u, or M); the relative ones follow their chiefs.
void draw_phase(Scenario& s) {
  const double offset_deg = draw_phase_offset_deg(s.seed, s.phase_window_deg);
  const double d_rad = (offset_deg - s.phase_offset_deg) * astro::kDegToRad;
  s.phase_offset_deg = offset_deg;
  if (d_rad == 0.0) return;
  for (auto& sc : s.spacecraft) {
    auto& o = sc.orbit;
    if (o.kind == InitialOrbit::Kind::kQns) o.qns.u_rad += d_rad;
    if (o.kind == InitialOrbit::Kind::kKepler) o.kepler.M_rad += d_rad;
  }
}

// A standard normal draw from two uniforms of the seed's stream `tag`
// (Box-Muller): the same bytes on every platform.
double normal_from_seed(std::uint64_t seed, std::uint64_t tag) {
  const double u1 = 1.0 - uniform_from_seed(seed, tag);  // (0, 1]
  const double u2 = uniform_from_seed(seed, tag + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * astro::kPi * u2);
}

// 64-bit FNV-1a of an observer's id: its own streams.
std::uint64_t id_hash(const std::string& id) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : id) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ULL;
  return h;
}

// Each fault's clock residual after the ground's correction.
void draw_clock_faults(Scenario& s) {
  for (auto& f : s.faults) {
    const std::uint64_t h = id_hash(f.observer);
    f.time_tag_offset_drawn_s = f.time_tag_offset_sigma_s * normal_from_seed(s.seed, h ^ 0x7461676f6666ULL);  // "tagoff"
    f.time_tag_drift_drawn_ppm =
        f.time_tag_drift_sigma_ppm * normal_from_seed(s.seed, h ^ 0x7461676472ULL);  // "tagdr"
  }
}

}  // namespace

void set_seed(Scenario& s, std::uint64_t seed) {
  s.seed = seed;
  for (auto* f : {&s.force_model, &s.onboard_force_model}) f->space_weather.seed = seed;
  draw_epoch(s);
  draw_phase(s);
  draw_clock_faults(s);
}

void set_epoch_window(Scenario& s, double window_s) {
  if (!(window_s >= 0.0 && window_s <= Scenario::kMaxEpochWindowS)) {
    throw std::invalid_argument("epoch window must lie in [0 s, 30 days], got " + fmt_num(window_s) + " s");
  }
  s.epoch_window_s = window_s;
  draw_epoch(s);
}

void set_phase_window(Scenario& s, double window_deg) {
  if (!(window_deg >= 0.0 && window_deg <= 360.0)) {
    throw std::invalid_argument("phase window must lie in [0, 360] deg, got " + fmt_num(window_deg) + " deg");
  }
  s.phase_window_deg = window_deg;
  draw_phase(s);
}

Scenario load_scenario(const std::string& path) {
  Scenario s;
  auto diagnostics = load(path, s);
  if (!diagnostics.empty()) throw ScenarioError(std::move(diagnostics));
  return s;
}

std::vector<Diagnostic> validate_scenario_file(const std::string& path) {
  Scenario s;
  return load(path, s);
}

std::vector<std::string> services(const Scenario& s) {
  std::vector<std::string> out{"truth", "camera-renderer", "crosslink-emulator"};
  for (const auto& o : s.observers) out.push_back("observer-" + o.spacecraft);
  out.emplace_back("recorder");
  return out;
}

}  // namespace artms::config
