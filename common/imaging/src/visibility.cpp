#include "artms/imaging/visibility.hpp"
