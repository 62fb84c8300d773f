/* TEST HARNESS (td2adaptor): the few TOPPERS/ASP 1.9 kernel types and services generated code uses. */
#ifndef TOPPERS_KERNEL_H
#define TOPPERS_KERNEL_H

#include <stdint.h>

typedef int ID;
typedef int ER;
typedef int PRI;
typedef unsigned int ATR;
typedef uint32_t RELTIM;

#define E_OK 0
#define E_CTX (-25)
#define TA_NULL 0U
#define TA_ACT 0x02U
#define TA_TPRI 0x01U

#ifndef TOPPERS_MACRO_ONLY
#ifdef __cplusplus
extern "C" {
#endif
ER act_tsk(ID tskid);
ER slp_tsk(void);
ER dly_tsk(RELTIM dlytim);
ER wai_sem(ID semid);
ER sig_sem(ID semid);
#ifdef __cplusplus
}
#endif
#endif /* TOPPERS_MACRO_ONLY */

#endif /* TOPPERS_KERNEL_H */
