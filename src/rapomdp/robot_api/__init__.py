"""A recogniser-and-planner a robot program calls with depth images (docs/robot-api.md).

:class:`~rapomdp.robot_api.recognizer.ActiveRecognizer` runs a finished workspace's method on
real depth images by the closed loop's rules; :mod:`~rapomdp.robot_api.wire` is the server's
message format and :mod:`~rapomdp.robot_api.server` the local server (``rapomdp serve``) and
its Python client. Nothing but the command line imports this package.
"""
