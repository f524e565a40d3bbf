# Branch "layout" (issue 29, item 6): the model blocks moved from models/ to models/blocks/,
# the kernel loader from the package models/native/ to the module models/native.py, and the
# C kernels beside the Python they speed up. Apply to another branch with:
#   git ls-files '*.py' '*.md' '*.toml' '*.c' '*.h' Makefile | xargs sed -E -i -f tools/layout_renames.sed
# Idempotent: a second pass changes nothing.
s#\bmodels([./])(deck_flexure|first_order_sensor|gauss_markov|hrg_platform|hrg_platform_gyro|land_vehicle|lever_arm|master_ins|platform_accelerometer|ship_motion|stationary_base|strapdown_imu|turntable)\b#models\1blocks\1\2#g
