#include "artms/io/oem.hpp"

#include <cstdio>
#include <fstream>
#include <istream>
#include <map>
#include <ostream>
#include <sstream>
#include <stdexcept>

namespace artms::io {
namespace {

// OEM epochs: "YYYY-MM-DDThh:mm:ss.ffffff" (UTC, no zone designator).
std::string oem_epoch(astro::TimeTT t) {
  std::string s = astro::utc_string(t, 6);
  s.pop_back();  // drop 'Z'
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

}  // namespace

namespace {

void write_meta(std::ostream& out, const std::string& name, const std::string& id, astro::TimeTT start,
                astro::TimeTT stop) {
  out << "\nMETA_START\n";
  out << "OBJECT_NAME = " << name << "\n";
  out << "OBJECT_ID = " << id << "\n";
  out << "CENTER_NAME = EARTH\n";
  out << "REF_FRAME = EME2000\n";
  out << "TIME_SYSTEM = UTC\n";
  out << "START_TIME = " << oem_epoch(start) << "\n";
  out << "STOP_TIME = " << oem_epoch(stop) << "\n";
  out << "META_STOP\n\n";
}

std::string data_line(const OemSample& s) {
  char line[256];
  const auto& r = s.x_eci.r_m;
  const auto& v = s.x_eci.v_mps;
  std::snprintf(line, sizeof line, "%s %.9f %.9f %.9f %.12f %.12f %.12f\n", oem_epoch(s.t).c_str(), r.x() * 1e-3,
                r.y() * 1e-3, r.z() * 1e-3, v.x() * 1e-3, v.y() * 1e-3, v.z() * 1e-3);
  return line;
}

}  // namespace

struct OemStreamWriter::Part {
  std::string tmp_path;
  std::ofstream out;
  astro::TimeTT first, last;
  bool any = false;
};

OemStreamWriter::OemStreamWriter(std::string path, astro::TimeTT creation, std::string originator)
    : path_(std::move(path)), creation_(creation), originator_(std::move(originator)) {}

OemStreamWriter::~OemStreamWriter() {
  for (auto& [name, p] : parts_) {
    p->out.close();
    std::remove(p->tmp_path.c_str());
  }
}

void OemStreamWriter::add(const std::string& object_name, const OemSample& s) {
  auto& p = parts_[object_name];
  if (!p) {
    p = std::make_unique<Part>();
    p->tmp_path = path_ + "." + object_name + ".part";
    p->out.open(p->tmp_path);
    if (!p->out) throw std::runtime_error("cannot write " + p->tmp_path);
  }
  if (p->any && !(p->last < s.t)) {
    throw std::invalid_argument("OemStreamWriter: sample times of " + object_name + " are not strictly increasing");
  }
  if (!p->any) p->first = s.t;
  p->any = true;
  p->last = s.t;
  p->out << data_line(s);
}

void OemStreamWriter::finish(const std::vector<std::string>& object_order) {
  bool any = false;
  for (const auto& n : object_order) any = any || (parts_.count(n) && parts_.at(n)->any);
  if (!any) return;
  std::ofstream out(path_);
  if (!out) throw std::runtime_error("cannot write OEM file " + path_);
  out << "CCSDS_OEM_VERS = 2.0\n";
  out << "CREATION_DATE = " << oem_epoch(creation_) << "\n";
  out << "ORIGINATOR = " << originator_ << "\n";
  for (const auto& n : object_order) {
    auto it = parts_.find(n);
    if (it == parts_.end() || !it->second->any) continue;
    auto& p = *it->second;
    p.out.close();
    write_meta(out, n, n, p.first, p.last);
    std::ifstream in(p.tmp_path);
    out << in.rdbuf();
  }
  if (!out) throw std::runtime_error("error while writing OEM file " + path_);
}

void write_oem(std::ostream& out, const OemFile& oem) {
  out << "CCSDS_OEM_VERS = 2.0\n";
  out << "CREATION_DATE = " << oem_epoch(oem.creation) << "\n";
  out << "ORIGINATOR = " << oem.originator << "\n";
  for (const OemSegment& seg : oem.segments) {
    if (seg.samples.empty()) {
      throw std::invalid_argument("write_oem: segment for " + seg.object_name + " has no samples");
    }
    for (std::size_t k = 1; k < seg.samples.size(); ++k) {
      if (!(seg.samples[k - 1].t < seg.samples[k].t)) {
        throw std::invalid_argument("write_oem: sample times of " + seg.object_name +
                                    " are not strictly increasing");
      }
    }
    write_meta(out, seg.object_name, seg.object_id, seg.samples.front().t, seg.samples.back().t);
    for (const OemSample& s : seg.samples) out << data_line(s);
  }
}

void write_oem_file(const std::string& path, const OemFile& oem) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write OEM file " + path);
  write_oem(out, oem);
  if (!out) throw std::runtime_error("error while writing OEM file " + path);
}

OemFile read_oem(std::istream& in, const std::string& name) {
  OemFile oem;
  std::string raw;
  int line_no = 0;
  const auto fail = [&](const std::string& why) {
    throw std::runtime_error(name + ":" + std::to_string(line_no) + ": " + why);
  };
  enum class State { kHeader, kMeta, kData, kCovariance } state = State::kHeader;
  bool have_version = false, have_creation = false, have_originator = false;
  std::map<std::string, std::string> meta;
  astro::TimeTT start{}, stop{};
  OemSegment* seg = nullptr;
  while (std::getline(in, raw)) {
    ++line_no;
    const std::string line = trim(raw);
    if (line.empty() || line.rfind("COMMENT", 0) == 0) continue;
    const auto eq = line.find('=');
    const std::string key = eq == std::string::npos ? line : trim(line.substr(0, eq));
    const std::string value = eq == std::string::npos ? "" : trim(line.substr(eq + 1));
    if (line == "META_START") {
      if (state == State::kMeta) fail("META_START inside a META block");
      if (!have_version || !have_creation || !have_originator) {
        fail("header lacks CCSDS_OEM_VERS, CREATION_DATE or ORIGINATOR");
      }
      state = State::kMeta;
      meta.clear();
      continue;
    }
    if (line == "META_STOP") {
      if (state != State::kMeta) fail("META_STOP without META_START");
      for (const char* k : {"OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM",
                            "START_TIME", "STOP_TIME"}) {
        if (!meta.count(k)) fail(std::string("META block lacks mandatory keyword ") + k);
      }
      if (meta["TIME_SYSTEM"] != "UTC") fail("only TIME_SYSTEM = UTC is supported");
      if (meta["REF_FRAME"] != "EME2000") fail("only REF_FRAME = EME2000 is supported");
      try {
        start = astro::tt_from_utc_string(meta["START_TIME"]);
        stop = astro::tt_from_utc_string(meta["STOP_TIME"]);
      } catch (const std::exception& e) {
        fail(e.what());
      }
      oem.segments.push_back({meta["OBJECT_NAME"], meta["OBJECT_ID"], {}});
      seg = &oem.segments.back();
      state = State::kData;
      continue;
    }
    if (line == "COVARIANCE_START") {
      state = State::kCovariance;
      continue;
    }
    if (line == "COVARIANCE_STOP") {
      state = State::kData;
      continue;
    }
    switch (state) {
      case State::kHeader:
        if (key == "CCSDS_OEM_VERS") {
          if (value != "2.0") fail("CCSDS_OEM_VERS is '" + value + "', expected 2.0");
          have_version = true;
        } else if (key == "CREATION_DATE") {
          try {
            oem.creation = astro::tt_from_utc_string(value);
          } catch (const std::exception& e) {
            fail(e.what());
          }
          have_creation = true;
        } else if (key == "ORIGINATOR") {
          oem.originator = value;
          have_originator = true;
        } else {
          fail("unexpected header line '" + line + "'");
        }
        break;
      case State::kMeta:
        if (eq == std::string::npos) fail("expected KEY = value in META block");
        meta[key] = value;
        break;
      case State::kCovariance:
        break;
      case State::kData: {
        std::istringstream ls(line);
        std::string epoch;
        double v[6];
        ls >> epoch;
        for (double& x : v) {
          if (!(ls >> x)) fail("data line needs an epoch and six numbers");
        }
        // Optional accelerations may follow; anything else is an error.
        double extra = 0.0;
        int n_extra = 0;
        while (ls >> extra) ++n_extra;
        if (!ls.eof() || (n_extra != 0 && n_extra != 3)) fail("malformed data line");
        OemSample s;
        try {
          s.t = astro::tt_from_utc_string(epoch);
        } catch (const std::exception& e) {
          fail(e.what());
        }
        if (s.t < start || stop < s.t) fail("epoch " + epoch + " outside START_TIME..STOP_TIME");
        if (!seg->samples.empty() && !(seg->samples.back().t < s.t)) {
          fail("epochs not strictly increasing");
        }
        s.x_eci.r_m = astro::Vec3(v[0], v[1], v[2]) * 1e3;
        s.x_eci.v_mps = astro::Vec3(v[3], v[4], v[5]) * 1e3;
        seg->samples.push_back(s);
        break;
      }
    }
  }
  if (state == State::kMeta) fail("file ends inside a META block");
  if (oem.segments.empty()) fail("no ephemeris segment (META_START ... META_STOP) found");
  for (const auto& s : oem.segments) {
    if (s.samples.empty()) fail("segment " + s.object_name + " has no data lines");
  }
  return oem;
}

OemFile read_oem_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open OEM file " + path);
  return read_oem(in, path);
}

}  // namespace artms::io
