#include "fits.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace artms::imp_tool {

namespace {

std::string message(int status) {
  char text[FLEN_STATUS];
  fits_get_errstatus(status, text);
  return text;
}

// Closes the file on every path out.
struct File {
  fitsfile* f = nullptr;
  ~File() {
    int status = 0;
    if (f) fits_close_file(f, &status);
  }
};

}  // namespace

FitsFrame read_fits(const std::string& path, bool bottom_first) {
  FitsFrame out;
  File file;
  int status = 0;
  // "[...]" suffixes are CFITSIO's extended syntax: open the file as named.
  if (fits_open_diskfile(&file.f, path.c_str(), READONLY, &status) ||
      fits_movabs_hdu(file.f, 1, nullptr, &status)) {
    throw std::runtime_error(path + ": cannot read FITS (" + message(status) + ")");
  }
  int naxis = 0;
  fits_get_img_dim(file.f, &naxis, &status);
  if (status == 0 && naxis == 0) {
    // An empty primary HDU: the first image extension.
    int hdutype = 0;
    fits_movrel_hdu(file.f, 1, &hdutype, &status);
    if (status == 0 && hdutype != IMAGE_HDU) {
      throw std::runtime_error(path + ": FITS has no image in its primary HDU or first extension");
    }
    fits_get_img_dim(file.f, &naxis, &status);
  }
  long dims[2] = {0, 0};
  fits_get_img_size(file.f, 2, dims, &status);
  if (status) throw std::runtime_error(path + ": FITS image header (" + message(status) + ")");
  if (naxis != 2 || dims[0] <= 0 || dims[1] <= 0) {
    throw std::runtime_error(path + ": FITS image is " + std::to_string(naxis) + "-dimensional, expected 2");
  }
  const long n = dims[0] * dims[1];
  std::vector<double> v(static_cast<std::size_t>(n));
  long first[2] = {1, 1};
  int anynul = 0;
  double nulval = 0.0;
  if (fits_read_pix(file.f, TDOUBLE, first, n, &nulval, v.data(), &anynul, &status)) {
    throw std::runtime_error(path + ": FITS pixels (" + message(status) + ")");
  }
  out.image.width = static_cast<int>(dims[0]);
  out.image.height = static_cast<int>(dims[1]);
  out.image.pixels.resize(static_cast<std::size_t>(n));
  for (long k = 0; k < n; ++k) {
    const double x = std::isfinite(v[static_cast<std::size_t>(k)]) ? v[static_cast<std::size_t>(k)] : 0.0;
    out.image.pixels[static_cast<std::size_t>(k)] = static_cast<std::uint16_t>(std::lround(std::clamp(x, 0.0, 65535.0)));
  }
  for (int r = 0; bottom_first && r < out.image.height / 2; ++r) {
    std::swap_ranges(out.image.pixels.begin() + static_cast<long>(r) * dims[0],
                     out.image.pixels.begin() + static_cast<long>(r + 1) * dims[0],
                     out.image.pixels.begin() + static_cast<long>(out.image.height - 1 - r) * dims[0]);
  }
  char date[FLEN_VALUE] = "", timesys[FLEN_VALUE] = "UTC";
  int st = 0;
  fits_read_key(file.f, TSTRING, "DATE-OBS", date, nullptr, &st);
  if (st != 0 || date[0] == '\0') {
    out.time_note = "no DATE-OBS in the header";
    return out;
  }
  st = 0;
  fits_read_key(file.f, TSTRING, "TIMESYS", timesys, nullptr, &st);
  std::string iso = date;
  if (iso.find('T') == std::string::npos) {
    throw std::runtime_error(path + ": DATE-OBS '" + iso + "' has no time of day (expected YYYY-MM-DDThh:mm:ss)");
  }
  if (iso.back() != 'Z') iso += "Z";
  astro::TimeTT t;
  try {
    const std::string sys = timesys;
    if (sys == "UTC" || sys.empty()) {
      t = astro::tt_from_utc_string(iso);
    } else if (sys == "TT" || sys == "TAI") {
      // Read as a UTC string, then undo the UTC offset at that date
      // (TT - UTC = TAI - UTC + 32.184 s).
      const astro::TimeTT as_utc = astro::tt_from_utc_string(iso);
      const int dat = astro::tai_minus_utc_s(std::stoi(iso.substr(0, 4)), std::stoi(iso.substr(5, 2)),
                                             std::stoi(iso.substr(8, 2)));
      t = as_utc.plus_seconds(-(dat + 32.184) + (sys == "TAI" ? 32.184 : 0.0));
    } else {
      throw std::runtime_error("TIMESYS '" + sys + "' (UTC, TT or TAI expected)");
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": DATE-OBS '" + std::string(date) + "': " + e.what());
  }
  double exptime = 0.0;
  st = 0;
  fits_read_key(file.f, TDOUBLE, "EXPTIME", &exptime, nullptr, &st);
  if (st == 0 && std::isfinite(exptime) && exptime > 0.0) {
    out.t_mid = t.plus_seconds(0.5 * exptime);
    out.time_note = "DATE-OBS + EXPTIME / 2";
  } else {
    out.t_mid = t;
    out.time_note = "DATE-OBS (no EXPTIME)";
  }
  return out;
}

}  // namespace artms::imp_tool
