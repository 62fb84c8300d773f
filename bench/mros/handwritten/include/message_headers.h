/* Hand-written glue (benchmark baseline): the application's message headers, dispatch and MD5 lookup. */
#ifndef HW_MESSAGE_HEADERS_H
#define HW_MESSAGE_HEADERS_H

#include "ar_track_alvar_msgs/AlvarMarkers.h"
#include "robot_local_control_msgs/Status.h"
#include "std_msgs/Float64.h"

static void callCallback(int id, void (*fp)(void *), char *rbuf)
{
    switch (id) {
    case ROBOT_LOCAL_CONTROL_MSGS_STATUS_MSG_ID:
        subtask_methods::CallCallbackFuncs<ROBOT_LOCAL_CONTROL_MSGS_STATUS_MSG_ID>::call(fp, rbuf);
        break;
    case AR_TRACK_ALVAR_MSGS_ALVARMARKERS_MSG_ID:
        subtask_methods::CallCallbackFuncs<AR_TRACK_ALVAR_MSGS_ALVARMARKERS_MSG_ID>::call(fp, rbuf);
        break;
    }
}

static const char *getMD5Sum(int id)
{
    switch (id) {
    case ROBOT_LOCAL_CONTROL_MSGS_STATUS_MSG_ID:
        return message_traits::MD5Sum<ROBOT_LOCAL_CONTROL_MSGS_STATUS_MSG_ID>::value();
    case AR_TRACK_ALVAR_MSGS_ALVARMARKERS_MSG_ID:
        return message_traits::MD5Sum<AR_TRACK_ALVAR_MSGS_ALVARMARKERS_MSG_ID>::value();
    case STD_MSGS_FLOAT64_MSG_ID:
        return message_traits::MD5Sum<STD_MSGS_FLOAT64_MSG_ID>::value();
    }
    return NULL;
}

#endif
