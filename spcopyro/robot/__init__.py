"""What connects a fit to a robot: importing rosbags (:mod:`~spcopyro.robot.rosbag`), simulating
a robot's observations on a map file (:mod:`~spcopyro.robot.map_simulation`), updating a fit
online as observations arrive (:mod:`~spcopyro.robot.online`), Nav2 masks
(:mod:`~spcopyro.robot.nav2`) and navigation from instructions
(:mod:`~spcopyro.robot.navigation`)."""
