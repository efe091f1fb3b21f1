// CCSDS Orbit Ephemeris Message 2.0 (CCSDS 502.0-B-2), KVN form: writer and
// a reader strict enough to check what the writer and the recorder produce.
// Positions in km, velocities in km/s in the file; SI in memory.
#pragma once

#include <iosfwd>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "artms/astro/frames.hpp"
#include "artms/astro/time.hpp"

namespace artms::io {

struct OemSample {
  astro::TimeTT t;
  astro::StateVector x_eci;  // EME2000 (J2000), m and m/s
};

struct OemSegment {
  std::string object_name;
  std::string object_id;
  std::vector<OemSample> samples;  // strictly increasing in time
};

struct OemFile {
  std::string originator = "ARTMS-EMULATOR";
  // CREATION_DATE: the caller provides it so that identical runs give
  // identical files (the recorder passes the scenario epoch).
  astro::TimeTT creation;
  std::vector<OemSegment> segments;
};

// Writes KVN with CENTER_NAME = EARTH, REF_FRAME = EME2000, TIME_SYSTEM = UTC.
// Throws std::invalid_argument for an empty segment or non-increasing times.
void write_oem(std::ostream& out, const OemFile& oem);

// Writes an OEM file of several objects without holding the samples in
// memory (long runs): samples go to one temporary file per object next to
// `path` (strictly increasing times per object, else std::invalid_argument),
// and finish() writes the same text write_oem would, segments in the order
// given, then removes the temporary files.
class OemStreamWriter {
 public:
  OemStreamWriter(std::string path, astro::TimeTT creation, std::string originator = "ARTMS-EMULATOR");
  ~OemStreamWriter();
  OemStreamWriter(const OemStreamWriter&) = delete;
  OemStreamWriter& operator=(const OemStreamWriter&) = delete;
  void add(const std::string& object_name, const OemSample& s);
  // Objects without samples are skipped; nothing is written if none has any.
  void finish(const std::vector<std::string>& object_order);

 private:
  struct Part;
  std::string path_;
  astro::TimeTT creation_;
  std::string originator_;
  std::map<std::string, std::unique_ptr<Part>> parts_;
};
void write_oem_file(const std::string& path, const OemFile& oem);

// Parses KVN OEM 2.0 (header, META blocks, data lines; COMMENT lines and
// covariance blocks skipped). Throws std::runtime_error naming the line on
// anything that is not OEM 2.0 (missing mandatory keywords, bad numbers,
// times outside START_TIME..STOP_TIME, unsupported frame/time system).
OemFile read_oem(std::istream& in, const std::string& name_for_errors = "<oem>");
OemFile read_oem_file(const std::string& path);

}  // namespace artms::io
