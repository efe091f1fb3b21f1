#include "artms/imp/detection.hpp"
