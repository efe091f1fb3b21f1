#include "artms/imaging/image.hpp"
