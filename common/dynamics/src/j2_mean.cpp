#include "artms/dynamics/j2_mean.hpp"
