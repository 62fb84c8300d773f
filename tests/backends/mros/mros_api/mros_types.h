/* TEST HARNESS (td2adaptor): the mROS basic types mros_usr_config.h relies on. */
#ifndef _MROS_TYPES_H_
#define _MROS_TYPES_H_

#include <stdint.h>

typedef uint32_t mros_uint32;
typedef int mRosReturnType;
typedef uint32_t mRosSizeType;

#endif /* _MROS_TYPES_H_ */
