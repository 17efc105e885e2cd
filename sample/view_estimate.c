/* placeholder: being written */
#include "mim_sample.h"
