def test_import():
    import stns_experiments
    assert stns_experiments.__doc__
