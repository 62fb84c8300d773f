"""Serving one robot: admission and routing of inbound events (`engine`), procedure missions and ROS action
goals (`goals`), property events per message (`streams`), the replay guard (`replay`), the mission ledger
(`ledger`) and the words of failures (`words`)."""
