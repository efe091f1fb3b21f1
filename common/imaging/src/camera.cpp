#include "artms/imaging/camera.hpp"
