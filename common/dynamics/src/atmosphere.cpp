#include "artms/dynamics/atmosphere.hpp"
