#include "artms/imp/qmethod.hpp"
