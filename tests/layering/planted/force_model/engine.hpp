#pragma once
#include "force_model/force_model.hpp"
