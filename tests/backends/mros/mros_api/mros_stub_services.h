/* TEST HARNESS (td2adaptor): what the ros.cpp stand-in (mros_stub_lib.cpp) needs from its environment.
 * The host loopback bus (mros_stub_bus.cpp) implements these; on the target they stay undefined (objects
 * are compiled and their symbols checked, not linked). */
#ifndef TD2A_MROS_STUB_SERVICES_H
#define TD2A_MROS_STUB_SERVICES_H

#ifdef __cplusplus
extern "C" {
#endif

void stub_node(const char *name);
void *stub_add_endpoint(const char *topic, const char *datatype, int type_id, const char *md5,
                        const char *definition, int queue_size, int publisher, void (*fp)(void *));
char *stub_alloc(void *publisher, unsigned int size);
void stub_sent(void *publisher, char *block, unsigned int size, const char *written_end);
void stub_sleep(int rate);
/* mROS's delivery entry (as in ros.cpp): a received block (length prefix + message) to a callback. */
void mros_topic_callback(int type_id, void (*fp)(void *), char *block);

#ifdef __cplusplus
}
#endif

#endif /* TD2A_MROS_STUB_SERVICES_H */
