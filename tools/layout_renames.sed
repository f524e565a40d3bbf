# Branch "layout" (issue 29, item 6): the model blocks moved from models/ to models/blocks/,
# the kernel loader from the package models/native/ to the module models/native.py, and the
# C kernels beside the Python they speed up. Apply to another branch with:
#   git ls-files '*.py' '*.md' '*.toml' '*.c' '*.h' Makefile | xargs sed -E -i -f tools/layout_renames.sed
# Idempotent: a second pass changes nothing.
s#\bmodels([./])(deck_flexure|first_order_sensor|gauss_markov|hrg_platform|hrg_platform_gyro|land_vehicle|lever_arm|master_ins|platform_accelerometer|ship_motion|stationary_base|strapdown_imu|turntable)\b#models\1blocks\1\2#g
# The C kernels beside the Python they speed up; one header of conventions beside conventions.py.
s#models/native/(strapdown|transfer_feedback|transfer_master|transfer_model|transfer_publish|transfer_ukf)\.c\b#cosim/alignment/\1.c#g
s#models/native/conventions\.h\b#models/conventions.h#g
# The kernels' one way of declaration: native.declare("name", argtypes, restype) -> native.kernel("name")
# (the signature now lives in the table KERNELS of models/native/__init__.py; edit by hand
# where the argument list spans lines).
s#native\.declare\(("[a-z_0-9]+"), [^)]*\)#native.kernel(\1)#g
s#models\.native\.declare\b#cosim.models.native.kernel#g
