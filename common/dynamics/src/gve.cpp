#include "artms/dynamics/gve.hpp"
