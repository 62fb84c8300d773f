/* TEST HARNESS (td2adaptor): the mROS OS abstraction types mros_usr_config.h relies on. */
#ifndef _MROS_OS_H_
#define _MROS_OS_H_

#include "kernel.h"

typedef ID mRosTaskIdType;

#endif /* _MROS_OS_H_ */
