from fall_predictor.cli import main

raise SystemExit(main())
