/* The application code that consumes the data (benchmark): the same job as handwritten/user.cpp, through
 * the generated component API. */
#include "adaptor_components.h"

static robot_local_control_msgs::Status status;
static ar_track_alvar_msgs::AlvarMarkers markers;

int user_poll(void)
{
    int n = 0;
    if (adaptor::availabilityComponent.get_value(status)) {
        n += (int)status.robot_status.battery.level;
    }
    if (adaptor::poseMarkerComponent.get_value(markers)) {
        n += (int)markers.markers.size();
    }
    return n;
}
