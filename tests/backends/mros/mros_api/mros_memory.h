/* TEST HARNESS (td2adaptor): memory-pool types and the two declaration macros of mROS's mros_memory.h
 * (same names and arguments; our own simple layout: one static array per block class). */
#ifndef _MROS_MEMORY_H_
#define _MROS_MEMORY_H_

#include "mros_types.h"

typedef struct {
    mRosSizeType max_memory_num;
    mRosSizeType memsize;
    char *memory;
} mRosMemoryConfigType;

typedef struct {
    mRosSizeType config_num;
} mRosMemoryManagerType;

#define MROS_MEMORY_CONFIG_DECLARE_ENTRY(entry_name, max_memory_num, memsize) \
    static char entry_name##_memory[(max_memory_num) * (memsize)]; \
    static mRosMemoryConfigType entry_name##_config = {(max_memory_num), (memsize), entry_name##_memory}

#define MROS_MEMORY_CONFIG_DECLARE_MANAGER(mem_manager_name, config_num) \
    mRosMemoryManagerType mem_manager_name = {(config_num)}

#endif /* _MROS_MEMORY_H_ */
