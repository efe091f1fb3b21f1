#include "artms/dynamics/gravity.hpp"
