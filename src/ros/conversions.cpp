#include "vwe_vo/ros/conversions.h"
