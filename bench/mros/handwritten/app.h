/* Hand-written mROS application equivalent to the generated RB-1 adaptor (benchmark baseline). */
#ifndef HW_APP_H
#define HW_APP_H

#include "kernel.h"

#ifdef __cplusplus
extern "C" {
#endif
#ifndef TOPPERS_MACRO_ONLY
extern void hw_pub_task(intptr_t exinf);
extern void hw_sub_task(intptr_t exinf);
#endif
#ifdef __cplusplus
}
#endif

#endif
