#include "artms/imaging/star_catalog.hpp"
