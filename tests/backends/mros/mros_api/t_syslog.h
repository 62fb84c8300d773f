/* TEST HARNESS (td2adaptor): TOPPERS syslog levels and the syslog service (format-checked here). */
#ifndef TOPPERS_T_SYSLOG_H
#define TOPPERS_T_SYSLOG_H

#define LOG_EMERG 0U
#define LOG_ALERT 1U
#define LOG_CRIT 2U
#define LOG_ERROR 3U
#define LOG_WARNING 4U
#define LOG_NOTICE 5U
#define LOG_INFO 6U
#define LOG_DEBUG 7U

#ifndef TOPPERS_MACRO_ONLY
#ifdef __cplusplus
extern "C" {
#endif
void syslog(unsigned int prio, const char *format, ...) __attribute__((format(printf, 2, 3)));
#ifdef __cplusplus
}
#endif
#endif /* TOPPERS_MACRO_ONLY */

#endif /* TOPPERS_T_SYSLOG_H */
