// The run folder's CSV files (docs/runtime.md, "Run folder") read by column
// name: one reader for every tool. No quoting (the run folder has none).
// A row whose field count differs from the header's is an error naming the
// file and line, never silently dropped; so is an unknown column or a field
// that is not a number where one is asked for. One exception: an unfinished
// last line (no newline: a process killed while writing) is left out and
// named by truncated_line().
#pragma once

#include <cstdint>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace artms::io {

// One line split on `sep` (a trailing empty field counts: "a,b," has 3).
inline std::vector<std::string> split_fields(const std::string& line, char sep = ',') {
  std::vector<std::string> out;
  std::string::size_type start = 0;
  for (;;) {
    const auto end = line.find(sep, start);
    out.push_back(line.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) return out;
    start = end + 1;
  }
}

class CsvTable {
 public:
  // Throws std::runtime_error: "<path>: cannot open", "<path>: empty (no
  // header)", "<path>:<line>: <n> fields, the header has <m>".
  static CsvTable read(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open");
    CsvTable t;
    t.path_ = path;
    std::string line;
    if (!std::getline(in, line)) throw std::runtime_error(path + ": empty (no header)");
    t.header_ = split_fields(line);
    for (std::size_t i = 0; i < t.header_.size(); ++i) t.column_[t.header_[i]] = i;
    int lineno = 1;
    while (std::getline(in, line)) {
      ++lineno;
      if (line.empty()) continue;
      auto f = split_fields(line);
      if (f.size() != t.header_.size() && in.eof()) {
        t.truncated_line_ = lineno;
        break;
      }
      if (f.size() != t.header_.size()) {
        throw std::runtime_error(path + ":" + std::to_string(lineno) + ": " + std::to_string(f.size()) +
                                 " fields, the header has " + std::to_string(t.header_.size()));
      }
      t.rows_.push_back(std::move(f));
      t.lines_.push_back(lineno);
    }
    return t;
  }

  [[nodiscard]] std::size_t size() const { return rows_.size(); }
  [[nodiscard]] bool empty() const { return rows_.empty(); }
  [[nodiscard]] bool has(const std::string& name) const { return column_.count(name) != 0; }
  [[nodiscard]] const std::vector<std::string>& header() const { return header_; }
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] int line(std::size_t row) const { return lines_.at(row); }
  // The unfinished last line left out (0: none).
  [[nodiscard]] int truncated_line() const { return truncated_line_; }
  // Throws naming the file when the column does not exist.
  [[nodiscard]] std::size_t column(const std::string& name) const {
    const auto it = column_.find(name);
    if (it == column_.end()) throw std::runtime_error(path_ + ":1: no column '" + name + "'");
    return it->second;
  }
  [[nodiscard]] const std::string& text(std::size_t row, const std::string& name) const {
    return rows_.at(row)[column(name)];
  }
  [[nodiscard]] const std::vector<std::string>& row(std::size_t row) const { return rows_.at(row); }
  // Numbers: throw "<path>:<line>: column '<name>': '<text>' is not a number".
  [[nodiscard]] double number(std::size_t row, const std::string& name) const {
    return parse<double>(row, name, [](const std::string& s, std::size_t* n) { return std::stod(s, n); });
  }
  [[nodiscard]] std::int64_t integer(std::size_t row, const std::string& name) const {
    return parse<std::int64_t>(row, name, [](const std::string& s, std::size_t* n) { return std::stoll(s, n); });
  }

 private:
  template <typename T, typename F>
  T parse(std::size_t row, const std::string& name, F f) const {
    const std::string& s = text(row, name);
    try {
      std::size_t n = 0;
      const T v = f(s, &n);
      if (n == s.size()) return v;
    } catch (const std::exception&) {
    }
    throw std::runtime_error(path_ + ":" + std::to_string(line(row)) + ": column '" + name + "': '" + s +
                             "' is not a number");
  }
  std::string path_;
  std::vector<std::string> header_;
  std::map<std::string, std::size_t> column_;
  std::vector<std::vector<std::string>> rows_;
  std::vector<int> lines_;
  int truncated_line_ = 0;
};

}  // namespace artms::io
