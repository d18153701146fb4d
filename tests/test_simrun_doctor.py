import mujoco

from simrun.doctor import check_environment


def test_mujoco_compiles_and_steps_a_real_model():
    report = check_environment(backends=())
    assert report.physics_ok, report.physics_error
    assert report.mujoco_version == mujoco.__version__
    major, minor, patch = (int(x) for x in mujoco.__version__.split(".")[:3])
    assert (major, minor, patch) >= (4, 0, 1), "mujoco-core 4.0.0 has the Newton Hessian bug"
