from fall_predictor.cli.main import main

raise SystemExit(main())
