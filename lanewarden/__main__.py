from lanewarden.cli import main

raise SystemExit(main())
