#include "artms/config/scenario.hpp"
