#include "artms/dynamics/shadow.hpp"
