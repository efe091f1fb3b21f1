// artms-oem-check FILE: parses a CCSDS OEM 2.0 KVN file with the project's
// strict reader and prints its segments; exit 1 with the reader's message
// (file:line) if it is not conforming.
#include <cstdio>

#include "artms/io/oem.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: artms-oem-check FILE.oem\n");
    return 2;
  }
  try {
    const auto oem = artms::io::read_oem_file(argv[1]);
    for (const auto& s : oem.segments) {
      std::printf("%s: %zu states, %s .. %s\n", s.object_name.c_str(), s.samples.size(),
                  artms::astro::utc_string(s.samples.front().t).c_str(),
                  artms::astro::utc_string(s.samples.back().t).c_str());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "artms-oem-check: %s\n", e.what());
    return 1;
  }
  return 0;
}
