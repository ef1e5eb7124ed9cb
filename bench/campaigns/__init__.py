"""Campaigns: seeded studies of the flight code on the simulation models.

Navigation (nav_campaign), LED pose from images (pose_campaign,
image_pose_consistency, centroid_calibration), feature pose (feature_pose),
thruster learning (thrusters), the modal estimator and its references
(modal_campaign, modal_batch_ml, modal_crb), the Clohessy-Wiltshire check
(cw_check). Built on bench.sim; run through bench.runner."""
