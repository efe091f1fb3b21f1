// FITS frames for artms-imp (CFITSIO, Debian libcfitsio-dev): the primary
// image (or the first image extension) as 16-bit values, and the header's
// observation time.
#pragma once

#include <optional>
#include <string>

#include "artms/astro/time.hpp"
#include "artms/imaging/image.hpp"

namespace artms::imp_tool {

struct FitsFrame {
  imaging::Image16 image;
  // Mid-exposure time: DATE-OBS (the start, UTC unless TIMESYS says TT or
  // TAI) plus EXPTIME / 2 when EXPTIME is given; nullopt without DATE-OBS.
  std::optional<astro::TimeTT> t_mid;
  std::string time_note;  // how t_mid was formed, or why there is none
};

// Integer images are read with BSCALE/BZERO applied (unsigned 16-bit FITS:
// BITPIX 16, BZERO 32768); floating-point and wider integer images are
// clipped to [0, 65535] and rounded. Throws std::runtime_error naming the
// path and CFITSIO's message for an unreadable file, an image that is not
// two-dimensional, or a DATE-OBS that does not parse.
// FITS counts rows from the bottom of the picture (row 1 at the bottom, as
// DS9 shows it): bottom_first (the standard) turns the image so that its
// first row is the top one (DESIGN.md section 7); a camera that writes its
// first readout row as FITS row 1 needs bottom_first = false.
FitsFrame read_fits(const std::string& path, bool bottom_first = true);

}  // namespace artms::imp_tool
