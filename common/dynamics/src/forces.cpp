#include "artms/dynamics/forces.hpp"
