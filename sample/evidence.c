/* placeholder: being written */
#include "mim_sampler.h"
