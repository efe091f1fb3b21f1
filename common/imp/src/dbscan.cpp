#include "artms/imp/dbscan.hpp"
