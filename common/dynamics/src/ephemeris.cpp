#include "artms/dynamics/ephemeris.hpp"
