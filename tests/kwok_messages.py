"""A valid identified-parameters set of the thesis kwok-current truth (node and suite tests)."""


def thesis_parameter_values(**changes):
    """
    Return the thesis truth as identified-parameter values, valid over 0..2 A (a dict).

    ``changes`` replace fields (``valid=0.0``, ``beta0=math.nan``, ...).
    """
    from mr_damper_model.identification import presets
    _, params = presets.thesis_kwok_current()
    values = dict(params, i_ref_a=2.0, window_end_s=1.0, current_min_a=0.0, current_max_a=2.0,
                  rmse_n=1.0, nrmse_percent=0.5, valid=1.0)
    values.update(changes)
    return values


def thesis_parameters_msg(**changes):
    """Return :func:`thesis_parameter_values` as ``mr_damper_interfaces/KwokParameters``."""
    from mr_damper_common.messages import kwok_parameters_msg
    return kwok_parameters_msg(thesis_parameter_values(**changes))
