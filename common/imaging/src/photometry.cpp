#include "artms/imaging/photometry.hpp"
