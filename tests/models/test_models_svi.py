import probaff.models
import probaff.models.variational.svi
import probaff.models.variational.vi


def test_fit_svi_lives_in_svi_and_is_re_exported():
    assert probaff.models.fit_svi is probaff.models.variational.svi.fit_svi
    assert probaff.models.SVIHistory is probaff.models.variational.svi.SVIHistory
    assert not hasattr(
        probaff.models.variational.vi, "fit_svi"
    )  # the model module does not import its fit


def test_mixture_helpers_are_re_exported():
    from probaff.models.gates import gated
    from probaff.models.mixture import model as mixture

    assert mixture.mixture_distribution is gated.mixture_distribution
    assert mixture.gated_probs is gated.gated_probs
    for name in probaff.models.__all__:
        assert hasattr(probaff.models, name), name
