"""The operator dashboard (`td2adaptor dashboard`): a web page of the fleet, built from the robots' own Thing
Descriptions on the bus.

One server process holds the only MQTT connection (`connection`), keeps what the bus says about each robot
(`fleet`: its retained TD, status, last error, live values and events, the forms its TD names), and serves a
static page (`static/`, plain ES modules) with live updates over server-sent events (`app`); `server` runs it.
The browser never sees a broker credential and can only publish on the topics a robot's TD names for its own
affordances.
"""
