#include "artms/imp/star_id.hpp"
