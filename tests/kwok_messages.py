"""A valid identified-parameters message of the thesis kwok-current truth (node tests)."""


def thesis_parameters_msg(**changes):
    """
    Return ``mr_damper_interfaces/KwokParameters`` of the thesis truth, valid over 0..2 A.

    ``changes`` replace fields (``valid=0.0``, ``beta0=math.nan``, ...).
    """
    from mr_damper_model import presets
    from mr_damper_model.messages import kwok_parameters_msg
    _, params = presets.thesis_kwok_current()
    values = dict(params, i_ref_a=2.0, window_end_s=1.0, current_min_a=0.0, current_max_a=2.0,
                  rmse_n=1.0, nrmse_percent=0.5, valid=1.0)
    values.update(changes)
    return kwok_parameters_msg(values)
